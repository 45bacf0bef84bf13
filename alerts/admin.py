from django.contrib import admin

from .models import Alert, Delivery


class DeliveryInline(admin.TabularInline):
    model = Delivery
    extra = 0
    can_delete = False
    readonly_fields = ("channel", "recipient", "status", "attempts", "last_error", "delivered_at")


@admin.register(Alert)
class AlertAdmin(admin.ModelAdmin):
    """Alerts are a record: shown, never edited."""

    list_display = ("at", "organisation", "kind", "severity", "title")
    list_filter = ("kind", "severity", "organisation")
    inlines = [DeliveryInline]

    def has_add_permission(self, request) -> bool:  # type: ignore[no-untyped-def]
        return False

    def has_change_permission(self, request, obj=None) -> bool:  # type: ignore[no-untyped-def]
        return False

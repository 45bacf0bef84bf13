from django.contrib import admin

from .models import Reservation, SeparationMinima


@admin.register(SeparationMinima)
class SeparationMinimaAdmin(admin.ModelAdmin):
    list_display = ("organisation", "horizontal_m", "vertical_m")


@admin.register(Reservation)
class ReservationAdmin(admin.ModelAdmin):
    list_display = ("drone", "kind", "starts_at", "ends_at", "ended_at", "end_reason")
    list_filter = ("kind",)
    readonly_fields = [f.name for f in Reservation._meta.fields]

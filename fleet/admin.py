from django.contrib import admin

from .models import CommandLog, ConnectionEvent, Drone, Membership, Organisation


class MembershipInline(admin.TabularInline):
    model = Membership
    extra = 0
    autocomplete_fields = ["user"]


@admin.register(Organisation)
class OrganisationAdmin(admin.ModelAdmin):
    list_display = ["name", "slug", "created_at"]
    search_fields = ["name", "slug"]
    prepopulated_fields = {"slug": ["name"]}
    inlines = [MembershipInline]


@admin.register(Membership)
class MembershipAdmin(admin.ModelAdmin):
    list_display = ["user", "organisation", "role", "created_at"]
    list_filter = ["role", "organisation"]
    search_fields = ["user__username", "organisation__name"]
    autocomplete_fields = ["user", "organisation"]


class ConnectionEventInline(admin.TabularInline):
    model = ConnectionEvent
    extra = 0
    readonly_fields = ["kind", "at", "reason"]
    can_delete = False
    max_num = 0
    ordering = ["-at"]


@admin.register(Drone)
class DroneAdmin(admin.ModelAdmin):
    list_display = [
        "drone_id",
        "organisation",
        "online",
        "armed",
        "airborne",
        "battery_remaining",
        "last_seen",
        "credentials_revoked",
    ]
    list_filter = ["organisation", "online", "armed", "airborne", "credentials_revoked"]
    search_fields = ["drone_id", "name"]
    readonly_fields = ["mqtt_password_hash", "last_seen", "created_at"]
    inlines = [ConnectionEventInline]


@admin.register(ConnectionEvent)
class ConnectionEventAdmin(admin.ModelAdmin):
    list_display = ["drone", "kind", "at", "reason"]
    list_filter = ["kind", "drone__organisation"]
    search_fields = ["drone__drone_id"]
    date_hierarchy = "at"


@admin.register(CommandLog)
class CommandLogAdmin(admin.ModelAdmin):
    list_display = ["command", "drone", "user", "outcome", "sent_at", "answered_at"]
    list_filter = ["outcome", "command", "drone__organisation"]
    search_fields = ["drone__drone_id", "request_id", "user__username"]
    date_hierarchy = "sent_at"
    readonly_fields = [f.name for f in CommandLog._meta.fields]

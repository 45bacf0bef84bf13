from django.contrib import admin

from logs.models import FlightLog


@admin.register(FlightLog)
class FlightLogAdmin(admin.ModelAdmin):
    list_display = ("name", "organisation", "owner", "status", "format", "size", "created_at")
    list_filter = ("status", "format", "organisation")
    search_fields = ("name", "owner__username")
    readonly_fields = ("id", "created_at", "processed_at")

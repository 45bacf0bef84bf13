"""The admin shows flight records and open flights; it never edits or deletes them."""

from __future__ import annotations

from typing import Any

from django.contrib import admin

from .models import FlightRecord, OpenFlight


class ReadOnlyAdmin(admin.ModelAdmin):
    def has_add_permission(self, request: Any, obj: Any = None) -> bool:
        return False

    def has_change_permission(self, request: Any, obj: Any = None) -> bool:
        return False

    def has_delete_permission(self, request: Any, obj: Any = None) -> bool:
        return False


@admin.register(FlightRecord)
class FlightRecordAdmin(ReadOnlyAdmin):
    list_display = ("started_at", "organisation", "drone_ident", "pilot_name", "duration_s")
    list_filter = ("origin", "organisation")
    search_fields = ("drone_ident", "pilot_name", "mission_name")


@admin.register(OpenFlight)
class OpenFlightAdmin(ReadOnlyAdmin):
    list_display = ("armed_at", "drone", "disarmed_at")

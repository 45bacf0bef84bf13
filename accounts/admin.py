"""The Django admin shows tokens, invitations and the audit trail; it never edits the
trail, nor keys or invitation links (only their hashes exist)."""

from __future__ import annotations

from typing import Any

from django.contrib import admin

from .models import ApiToken, AuditEvent, Invitation


class ReadOnlyAdmin(admin.ModelAdmin):
    def has_add_permission(self, request: Any, obj: Any = None) -> bool:
        return False

    def has_change_permission(self, request: Any, obj: Any = None) -> bool:
        return False


@admin.register(AuditEvent)
class AuditEventAdmin(ReadOnlyAdmin):
    list_display = ("at", "organisation", "actor_name", "action", "target", "outcome", "ip")
    list_filter = ("kind", "outcome", "organisation")
    search_fields = ("actor_name", "action", "target")

    def has_delete_permission(self, request: Any, obj: Any = None) -> bool:
        return False


@admin.register(ApiToken)
class ApiTokenAdmin(ReadOnlyAdmin):
    list_display = ("name", "user", "prefix", "scope", "expires_at", "revoked_at", "last_used_at")
    exclude = ("key_hash",)


@admin.register(Invitation)
class InvitationAdmin(ReadOnlyAdmin):
    list_display = ("email", "organisation", "role", "created_at", "expires_at", "accepted_at")
    exclude = ("key_hash",)

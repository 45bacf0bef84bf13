"""DRF permissions: membership of the object's organisation, and roles for commands."""

from __future__ import annotations

from rest_framework.permissions import SAFE_METHODS, BasePermission

from .models import Role
from .tenancy import role_in


class OrganisationRole(BasePermission):
    """Reading needs membership; writing needs `operator` (objects expose `.organisation`).

    Querysets are already filtered to the user's organisations, so outsiders get 404
    before this runs; this turns a viewer's write into 403.
    """

    write_role = Role.OPERATOR

    def has_permission(self, request, view) -> bool:  # type: ignore[no-untyped-def]
        return bool(request.user and request.user.is_authenticated)

    def has_object_permission(self, request, view, obj) -> bool:  # type: ignore[no-untyped-def]
        membership = role_in(request.user, obj.organisation)
        if membership is None:
            return False
        if request.method in SAFE_METHODS:
            return True
        return membership.allows(self.write_role)


def require_role(user, organisation, role: str) -> bool:  # type: ignore[no-untyped-def]
    membership = role_in(user, organisation)
    return bool(membership and membership.allows(role))

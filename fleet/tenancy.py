"""Which organisation a request acts for, and what the user may do there.

A user may belong to several organisations; the portal acts for one at a time (kept in
the session, switchable). The API filters by every organisation the user belongs to.
"""

from __future__ import annotations

from collections.abc import Callable

from django.http import HttpRequest, HttpResponse

from .models import Membership, Organisation

SESSION_KEY = "organisation_slug"


def memberships_for(user) -> list[Membership]:  # type: ignore[no-untyped-def]
    return list(Membership.objects.for_user(user))


def current_membership(request: HttpRequest) -> Membership | None:
    if not request.user.is_authenticated:
        return None
    memberships = memberships_for(request.user)
    if not memberships:
        return None
    wanted = request.session.get(SESSION_KEY) if hasattr(request, "session") else None
    for membership in memberships:
        if membership.organisation.slug == wanted:
            return membership
    return memberships[0]


def role_in(user, organisation: Organisation) -> Membership | None:  # type: ignore[no-untyped-def]
    if not user.is_authenticated:
        return None
    return (
        Membership.objects.filter(user=user, organisation=organisation)
        .select_related("organisation")
        .first()
    )


class OrganisationMiddleware:
    """Sets request.membership and request.organisation for the portal pages."""

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]):
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        membership = current_membership(request)
        request.membership = membership  # type: ignore[attr-defined]
        request.organisation = membership.organisation if membership else None  # type: ignore[attr-defined]
        return self.get_response(request)


def organisation_context(request: HttpRequest) -> dict:
    membership = getattr(request, "membership", None)
    return {
        "current_membership": membership,
        "current_organisation": membership.organisation if membership else None,
        "can_operate": bool(membership and membership.allows("operator")),
        "all_memberships": memberships_for(request.user)
        if getattr(request, "user", None) and request.user.is_authenticated
        else [],
    }

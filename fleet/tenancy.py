"""Which organisation a request acts for, and what the user may do there.

A user may belong to several organisations; the portal acts for one at a time (kept in
the session, switchable). The API filters by every organisation the user belongs to,
except for a request made with a token bound to one organisation: it reaches that one
only. `reach` is the one query every `for_user` lookup goes through, so the rule holds
for every view, consumer and API without any of them restating it.
"""

from __future__ import annotations

from typing import Any

from django.db.models import Q
from django.http import HttpRequest

from .models import Membership, Organisation

SESSION_KEY = "organisation_slug"
# Set on the user object of a request authenticated by a token made for one organisation.
BOUND_ATTR = "bound_organisation_id"


def bind(user: Any, organisation_id: int) -> None:
    """From now on this user object (a token's request) reaches `organisation_id` only."""
    setattr(user, BOUND_ATTR, organisation_id)


def reach(user: Any, *, via: str = "organisation") -> Q:
    """Rows whose organisation (`via`; "" for memberships themselves) the user belongs
    to, narrowed to the one organisation the user object is bound to, if any."""
    rule = Q(**{f"{via}__memberships__user": user}) if via else Q(user=user)
    bound = getattr(user, BOUND_ATTR, None)
    if bound is not None:
        rule &= Q(**{f"{via}_id" if via else "organisation_id": bound})
    return rule


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
    return Membership.objects.for_user(user).filter(organisation=organisation).first()


_CACHE_ATTR = "_acting_membership"


def acting_membership(request: HttpRequest) -> Membership | None:
    """The membership the portal acts for on this request, looked up once per request.

    Looked up on first use rather than by a middleware: an API request that never asks
    (a command) pays no query and no hop out of the event loop for it."""
    if not hasattr(request, _CACHE_ATTR):
        setattr(request, _CACHE_ATTR, current_membership(request))
    return getattr(request, _CACHE_ATTR)


def acting_organisation(request: HttpRequest) -> Organisation | None:
    membership = acting_membership(request)
    return membership.organisation if membership else None


def organisation_context(request: HttpRequest) -> dict:
    membership = acting_membership(request) if hasattr(request, "user") else None
    return {
        "current_membership": membership,
        "current_organisation": membership.organisation if membership else None,
        "can_operate": bool(membership and membership.allows("operator")),
        "all_memberships": memberships_for(request.user)
        if getattr(request, "user", None) and request.user.is_authenticated
        else [],
    }

"""The lookups every API view and page starts from, through the isolation rule: another
organisation's drone or organisation is as unknown as none (404)."""

from __future__ import annotations

from typing import Any

from django.http import Http404, HttpRequest
from rest_framework import exceptions

from .models import Drone, Membership, Organisation
from .tenancy import acting_organisation


def drone_or_404(user: Any, drone_id: str) -> Drone:
    """The user's drone with its organisation; DRF's NotFound otherwise."""
    drone = (
        Drone.objects.for_user(user)
        .select_related("organisation")
        .filter(drone_id=drone_id)
        .first()
    )
    if drone is None:
        raise exceptions.NotFound(f"Unknown drone {drone_id!r}.")
    return drone


def organisation_or_404(user: Any, slug: str) -> Organisation:
    """An organisation the user belongs to, by slug; DRF's NotFound otherwise."""
    membership = Membership.objects.for_user(user).filter(organisation__slug=slug).first()
    if membership is None:
        raise exceptions.NotFound(f"Unknown organisation {slug!r}.")
    return membership.organisation


def acting_organisation_or_404(request: HttpRequest) -> Organisation:
    """The organisation a portal page acts for; Http404 for a user of none."""
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    return organisation

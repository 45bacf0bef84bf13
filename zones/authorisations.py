"""Authorisations to fly in a zone that requires one: recorded by an organisation's admin
(who issued it, its reference, its expiry), kept in the audit trail (accounts listens
to their creation), and honoured by the checks until they expire (zones/enforcement.py)."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from django.db.models import QuerySet
from django.utils import timezone

from fleet.models import Membership, Organisation, Role

from .models import Authorisation, Restriction, Zone


class AuthorisationRefused(ValueError):
    """`status` is the HTTP answer; `field` the input at fault, if any."""

    def __init__(self, status: int, message: str, field: str = "") -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.field = field


def of_zone(user: Any, zone: Zone) -> QuerySet[Authorisation]:
    """The zone's authorisations held by the user's organisations."""
    mine = Membership.objects.for_user(user).values("organisation_id")
    return zone.authorisations.filter(organisation_id__in=mine).select_related(
        "organisation", "recorded_by"
    )


def _admin_organisation(user: Any, zone: Zone, slug: str | None) -> Organisation:
    """The organisation the authorisation is for: the zone's own, else the one named, else
    the only one the user administers. The user must be its admin."""
    admin_of = Membership.objects.for_user(user).filter(role=Role.ADMIN)
    if zone.organisation_id is not None:
        admin_of = admin_of.filter(organisation_id=zone.organisation_id)
    elif slug:
        admin_of = admin_of.filter(organisation__slug=slug)
    memberships = list(admin_of[:2])
    if len(memberships) == 1:
        return memberships[0].organisation
    if not memberships:
        raise AuthorisationRefused(403, "Only an organisation's admins record authorisations.")
    raise AuthorisationRefused(400, "Name the organisation (its slug).", "organisation")


def record(
    user: Any,
    zone: Zone,
    issued_by: str,
    reference: str,
    expires_at: datetime,
    organisation: str | None = None,
) -> Authorisation:
    if zone.restriction != Restriction.AUTHORISATION_REQUIRED:
        raise AuthorisationRefused(
            409,
            f"Zone {zone.identifier} is {zone.get_restriction_display().lower()}: "
            "it takes no authorisation.",
        )
    if expires_at <= timezone.now():
        raise AuthorisationRefused(400, "expires_at: must be in the future", "expires_at")
    return Authorisation.objects.create(
        zone=zone,
        organisation=_admin_organisation(user, zone, organisation),
        issued_by=issued_by,
        reference=reference,
        expires_at=expires_at,
        recorded_by=user,
    )


def as_dict(authorisation: Authorisation, now: datetime | None = None) -> dict:
    now = now or timezone.now()
    return {
        "id": authorisation.pk,
        "zone": authorisation.zone_id,
        "organisation": authorisation.organisation.slug,
        "issued_by": authorisation.issued_by,
        "reference": authorisation.reference,
        "expires_at": authorisation.expires_at.isoformat(),
        "expired": authorisation.expires_at <= now,
        "recorded_by": authorisation.recorded_by.get_username()
        if authorisation.recorded_by
        else None,
        "recorded_at": authorisation.recorded_at.isoformat(),
    }

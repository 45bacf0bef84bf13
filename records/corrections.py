"""Correcting a flight record: a new record that copies the one it corrects, changes what
the correction says, and names it (`corrects`). The record corrected stays as it was."""

from __future__ import annotations

from typing import Any

from django.contrib.auth import get_user_model
from django.db import IntegrityError, transaction
from django.utils import timezone

from batteries import usage
from fleet.models import Membership

from .models import FlightRecord

# What a correction may change; the rest of a record is what the telemetry said.
CORRECTABLE = (
    "pilot",
    "battery",
    "takeoff_at",
    "landing_at",
    "duration_s",
    "airborne_s",
    "distance_m",
    "max_height_m",
    "max_speed_ms",
    "max_distance_m",
    "battery_start",
    "battery_end",
    "energy_wh",
)
# Fields copied unchanged from the record corrected.
_COPIED = [
    f.name
    for f in FlightRecord._meta.concrete_fields
    if f.name not in ("id", "corrects", "correction_reason", "recorded_by", "recorded_at")
]


class CorrectionRefused(Exception):
    def __init__(self, status: int, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.field = field


def pilot_in(organisation_id: int, username: str) -> Any:
    """The member of the organisation with that username (a pilot must be one)."""
    user = get_user_model().objects.filter(username=username).first()
    if (
        user is None
        or not Membership.objects.filter(user=user, organisation_id=organisation_id).exists()
    ):
        raise CorrectionRefused(400, f"pilot: {username!r} is not a member", "pilot")
    return user


def correct(record: FlightRecord, changes: dict, *, reason: str, user: Any) -> FlightRecord:
    """The new record; 409 when `record` was corrected already (correct the newest)."""
    unknown = sorted(set(changes) - set(CORRECTABLE))
    if unknown:
        raise CorrectionRefused(400, f"{unknown[0]}: cannot be corrected", unknown[0])
    if not reason.strip():
        raise CorrectionRefused(400, "reason: say why the record is corrected", "reason")
    values = {name: getattr(record, name) for name in _COPIED}
    values.update(changes)
    if "pilot" in changes:
        values["pilot_name"] = changes["pilot"].get_username() if changes["pilot"] else ""
    try:
        with transaction.atomic():
            new = FlightRecord.objects.create(
                **values,
                corrects=record,
                correction_reason=reason.strip()[:500],
                recorded_by=user if getattr(user, "pk", None) else None,
                recorded_at=timezone.now(),
            )
            usage.retake(record, new)  # the pack (or its figures) may be what was corrected
            return new
    except IntegrityError:
        raise CorrectionRefused(
            409, "this record was corrected already: correct its newest version"
        ) from None


def history(record: FlightRecord) -> list[FlightRecord]:
    """The record's versions, oldest first, ending with the current one."""
    first = record
    while first.corrects_id is not None:
        first = FlightRecord.objects.get(pk=first.corrects_id)
    chain = [first]
    while True:
        following = FlightRecord.objects.filter(corrects=chain[-1]).first()
        if following is None:
            return chain
        chain.append(following)

"""Signing a maintenance task off: a new entry in the drone's maintenance log (who, when,
what was done, which parts), after which the schedule counts again from zero and a
bulletin is closed for that drone.

Who may sign off: the organisation's admins. A sign-off releases a drone to fly, the
same authority as the organisation's other airworthiness settings (Remote ID identities,
the envelope); an organisation makes its maintenance lead an admin. Anyone else: 403.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from django.db import IntegrityError, transaction

from fleet.models import Drone, Role
from fleet.permissions import require_role

from . import due
from .errors import Refused
from .models import Bulletin, LogEntry, Schedule
from .schedules import NOTES_MAX, text

FIELDS = ("schedule", "bulletin", "notes", "parts")
PARTS_MAX, PART_MAX = 50, 120


def may_sign_off(user: Any, drone: Drone) -> bool:
    return require_role(user, drone.organisation, Role.ADMIN)


def _parts(value: Any) -> list[str]:
    if value is None:
        return []
    if not isinstance(value, list) or len(value) > PARTS_MAX:
        raise Refused("parts", f"must be a list of at most {PARTS_MAX} part names")
    return [text(part, "parts", PART_MAX, required=True) for part in value]


def _item(drone: Drone, data: Mapping) -> due.Item:
    """The drone's item the body names by `schedule` or `bulletin` id (exactly one)."""
    named = [key for key in ("schedule", "bulletin") if data.get(key) is not None]
    if len(named) != 1:
        raise Refused("schedule", "name one schedule or one bulletin by its id")
    key = named[0]
    wanted = data[key]
    if isinstance(wanted, bool) or not isinstance(wanted, int):
        raise Refused(key, "must be an id")
    for item in due.items(drone):
        if (item.schedule_id if key == "schedule" else item.bulletin_id) == wanted:
            return item
    if key == "bulletin" and LogEntry.objects.filter(drone=drone, bulletin_id=wanted).exists():
        raise Refused(key, "this bulletin is signed off for this drone already", 409)
    raise Refused(key, f"no {key} {wanted} applies to drone {drone.drone_id}")


def sign_off(drone: Drone, data: Any, user: Any) -> LogEntry:
    """Add the sign-off to the drone's log; Refused (400/403/409) adds nothing."""
    if not may_sign_off(user, drone):
        raise Refused("non_field_errors", "only organisation admins may sign maintenance off", 403)
    if not isinstance(data, Mapping):
        raise Refused("non_field_errors", "must be a JSON object")
    unknown = sorted(set(data) - set(FIELDS))
    if unknown:
        raise Refused(unknown[0], "unknown field")
    item = _item(drone, data)
    notes = text(data.get("notes"), "notes", NOTES_MAX, required=True)
    parts = _parts(data.get("parts"))
    try:
        with transaction.atomic():
            return LogEntry.objects.create(
                organisation_id=drone.organisation_id,
                drone=drone,
                drone_ident=drone.drone_id,
                schedule=Schedule.objects.filter(pk=item.schedule_id).first(),
                bulletin=Bulletin.objects.filter(pk=item.bulletin_id).first(),
                item_name=item.name,
                signed_by=user,
                signed_by_name=user.get_username(),
                notes=notes,
                parts=parts,
                usage=[m.to_dict() for m in item.measures],
            )
    except IntegrityError:
        raise Refused(
            "bulletin", "this bulletin is signed off for this drone already", 409
        ) from None


def entry_dict(entry: LogEntry) -> dict:
    return {
        "id": entry.pk,
        "drone": entry.drone_ident,
        "item": entry.item_name,
        "schedule": entry.schedule_id,
        "bulletin": entry.bulletin_id,
        "signed_by": entry.signed_by_name,
        "signed_at": entry.signed_at.isoformat(),
        "notes": entry.notes,
        "parts": entry.parts,
        "usage": entry.usage,
    }

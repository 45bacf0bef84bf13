"""Writing maintenance schedules and issuing service bulletins: every field checked before
anything is stored, so a refused body (Refused names its field) changes nothing.

A schedule names one target, a drone of the organisation or a gear model, and at least one
trigger; each trigger is a positive interval (hours may be fractional, flights and days
are whole numbers) below a bound no real schedule reaches.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from django.utils import timezone

from fleet.models import Drone, Organisation

from .errors import Refused
from .models import Bulletin, Schedule

FIELDS = ("name", "drone", "model", "every_hours", "every_flights", "every_days", "notes")
TRIGGERS = ("every_hours", "every_flights", "every_days")
# Above these an interval is a typing error: 100 000 h is over eleven years aloft.
BOUNDS = {"every_hours": 100_000.0, "every_flights": 1_000_000, "every_days": 36_500}
WHOLE = ("every_flights", "every_days")
NAME_MAX, MODEL_MAX, NOTES_MAX, TITLE_MAX, TEXT_MAX = 120, 120, 2000, 200, 10_000


def _known(data: Any, allowed: tuple[str, ...]) -> Mapping:
    if not isinstance(data, Mapping):
        raise Refused("non_field_errors", "must be a JSON object")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise Refused(unknown[0], "unknown field")
    return data


def text(value: Any, field: str, limit: int, *, required: bool) -> str:
    """The stripped string; Refused when it is not one, too long, or empty but required."""
    if value is None and not required:
        return ""
    if not isinstance(value, str):
        raise Refused(field, "must be a string")
    value = value.strip()
    if required and not value:
        raise Refused(field, "must not be empty")
    if len(value) > limit:
        raise Refused(field, f"at most {limit} characters")
    return value


def interval(value: Any, field: str) -> float | int | None:
    """A positive, finite interval within its bound; whole for flights and days."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise Refused(field, "must be a number")
    if value <= 0:
        raise Refused(field, "must be greater than zero")
    if value > BOUNDS[field]:
        raise Refused(field, f"at most {BOUNDS[field]:g}")
    if field in WHOLE:
        if value != int(value):
            raise Refused(field, "must be a whole number")
        return int(value)
    return float(value)


def _target(organisation: Organisation, values: Mapping) -> tuple[Drone | None, str]:
    drone_id = values.get("drone") or None
    model = text(values.get("model"), "model", MODEL_MAX, required=False)
    if drone_id is not None and model:
        raise Refused("model", "name a drone or a gear model, not both")
    if drone_id is None:
        if not model:
            raise Refused("drone", "name a drone or a gear model (model)")
        return None, model
    if not isinstance(drone_id, str):
        raise Refused("drone", "must be a drone id")
    drone = Drone.objects.filter(organisation=organisation, drone_id=drone_id).first()
    if drone is None:
        raise Refused("drone", f"no drone {drone_id!r} in this organisation")
    return drone, ""


def parse(organisation: Organisation, values: Mapping) -> dict:
    """The schedule's model fields from a whole body (a change merged over the stored one)."""
    drone, model = _target(organisation, values)
    triggers = {field: interval(values.get(field), field) for field in TRIGGERS}
    if all(value is None for value in triggers.values()):
        raise Refused("every_hours", "give at least one of every_hours, every_flights, every_days")
    return {
        "name": text(values.get("name"), "name", NAME_MAX, required=True),
        "drone": drone,
        "model": model,
        **triggers,
        "notes": text(values.get("notes"), "notes", NOTES_MAX, required=False),
    }


def stored(schedule: Schedule) -> dict:
    """A stored schedule as the body that would make it."""
    return {
        "name": schedule.name,
        "drone": schedule.drone.drone_id if schedule.drone_id else None,
        "model": schedule.model,
        "every_hours": schedule.every_hours,
        "every_flights": schedule.every_flights,
        "every_days": schedule.every_days,
        "notes": schedule.notes,
    }


def create(organisation: Organisation, data: Any, user: Any) -> Schedule:
    fields = parse(organisation, _known(data, FIELDS))
    return Schedule.objects.create(organisation=organisation, created_by=user, **fields)


def change(schedule: Schedule, data: Any) -> Schedule:
    """Apply the fields given; the rest stay. Counting restarts only at a sign-off."""
    merged = {**stored(schedule), **_known(data, FIELDS)}
    fields = parse(schedule.organisation, merged)
    for name, value in fields.items():
        setattr(schedule, name, value)
    schedule.updated_at = timezone.now()
    schedule.save()
    return schedule


def issue_bulletin(organisation: Organisation, data: Any, user: Any) -> Bulletin:
    """A service bulletin for every drone of the model (`model`), or a finding on one drone
    (`drone`), open on each until signed off."""
    data = _known(data, ("model", "drone", "title", "text"))
    drone, model = _target(organisation, data)
    return Bulletin.objects.create(
        organisation=organisation,
        model=model,
        drone=drone,
        title=text(data.get("title"), "title", TITLE_MAX, required=True),
        text=text(data.get("text"), "text", TEXT_MAX, required=True),
        issued_by=user,
        issued_by_name=user.get_username(),
    )


def schedule_dict(schedule: Schedule) -> dict:
    return {
        "id": schedule.pk,
        **stored(schedule),
        "created_at": schedule.created_at.isoformat(),
        "updated_at": schedule.updated_at.isoformat(),
    }


def bulletin_dict(bulletin: Bulletin) -> dict:
    return {
        "id": bulletin.pk,
        "model": bulletin.model,
        "drone": bulletin.drone.drone_id if bulletin.drone_id else None,
        "title": bulletin.title,
        "text": bulletin.text,
        "issued_by": bulletin.issued_by_name,
        "issued_at": bulletin.issued_at.isoformat(),
    }

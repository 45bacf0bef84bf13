"""`startchain` / `stopchain` on `/control`, tracked as missions.

Named by settings.MISSION_START_STOP_HANDLERS, which `fleet.commands` calls.
"""

from __future__ import annotations

import base64
import binascii
import json
from typing import Any

from fleet.commands import CommandRefused
from fleet.models import Drone
from missions.models import Assignment, MissionStatus
from missions.services import MissionError, create_mission, start_mission, stop_mission


def _steps(mission: str) -> list:
    """The `mission` parameter: base64 of a bare list of steps or of a full payload."""
    try:
        data = json.loads(base64.b64decode(mission.encode("ascii"), validate=True))
    except (binascii.Error, ValueError, UnicodeError):
        raise CommandRefused(400, "mission: must be base64 of a JSON mission", "mission") from None
    if isinstance(data, dict):
        data = data.get("steps")
    if not isinstance(data, list):
        raise CommandRefused(400, "mission: must hold a list of steps", "mission")
    return data


def start_from_control(*, drone: Drone, user: Any, mission: str, confirmed: bool = False) -> dict:
    """Create the chain's mission and start it on the drone; a refusal by the envelope
    (or for want of a confirmation beyond its defaults) keeps its 409 and code."""
    try:
        created = create_mission(
            organisation=drone.organisation,
            name=f"Chain on {drone.drone_id}",
            steps=_steps(mission),
            user=user,
            confirmed=confirmed,
        )
    except MissionError as exc:
        if exc.code is not None:
            raise CommandRefused(exc.status, exc.message, "mission", exc.code) from None
        raise CommandRefused(400, f"mission: {exc}", "mission") from None
    try:
        started = start_mission(created, drone=drone, user=user, confirmed=confirmed)
    except MissionError as exc:
        created.delete()
        raise CommandRefused(exc.status, exc.message, exc.field, exc.code) from None
    return {
        "mission_id": str(started.mission.pk),
        "assignment_id": str(started.assignment.pk),
        "steps": len(started.assignment.step_indexes),
        "status": "sent",
    }


def stop_from_control(*, drone: Drone, user: Any) -> dict:
    assignment = (
        Assignment.objects.filter(
            drone=drone,
            status__in=Assignment.ACTIVE,
            mission__status__in=(MissionStatus.RUNNING, MissionStatus.PAUSED),
        )
        .select_related("mission")
        .order_by("-created_at")
        .first()
    )
    if assignment is None:
        raise CommandRefused(409, f"Drone {drone.drone_id} is not executing a mission.")
    try:
        stop_mission(assignment.mission, user=user, reason="stopchain from /control")
    except MissionError as exc:
        raise CommandRefused(exc.status, exc.message, exc.field) from None
    return {"mission_id": str(assignment.mission.pk), "status": "sent"}

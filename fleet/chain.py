"""Default `startchain` / `stopchain` (seed table 4.2): send the mission, track nothing.

Mission tracking belongs to the missions app; it replaces these through
settings.FLEET_CHAIN_HANDLERS with functions of the same signatures. These defaults
publish to `<id>/mission/in` (through the gateway) and answer at once with what was sent.
"""

from __future__ import annotations

import base64
import binascii
import json
import uuid
from typing import Any

from django.utils import timezone

from onboard import protocol

from . import link
from .commands import CommandRefused
from .models import CommandLog, Drone


def _steps_from_base64(mission: str) -> tuple[str, str, list[dict]]:
    """The seed's `mission`: base64 of either a full payload or a bare list of steps."""
    try:
        data = json.loads(base64.b64decode(mission.encode("ascii"), validate=True))
    except (binascii.Error, ValueError, UnicodeError):
        raise CommandRefused(400, "mission: must be base64 of a JSON mission", "mission") from None
    if isinstance(data, list):
        data = {"mission_id": uuid.uuid4().hex, "assignment_id": uuid.uuid4().hex, "steps": data}
    try:
        payload = protocol.parse_mission_payload(data)
    except protocol.ProtocolError as exc:
        raise CommandRefused(400, f"mission: {exc}", "mission") from None
    return payload.mission_id, payload.assignment_id, [s.to_dict() for s in payload.steps]


def start_chain(*, drone: Drone, user: Any, mission: str) -> dict:
    mission_id, assignment_id, steps = _steps_from_base64(mission)
    message = protocol.mission_start(mission_id, assignment_id, steps)
    link.send_to_drone(drone.drone_id, "mission", message.to_dict())
    _log(drone, user, "startchain", message.request_id, {"mission_id": mission_id})
    return {
        "mission_id": mission_id,
        "assignment_id": assignment_id,
        "steps": len(steps),
        "status": "sent",
    }


def stop_chain(*, drone: Drone, user: Any) -> dict:
    mission_id = (drone.mission or {}).get("mission_id")
    if not mission_id:
        raise CommandRefused(409, f"Drone {drone.drone_id} is not executing a mission.")
    message = protocol.MissionStop(protocol.new_request_id(), str(mission_id))
    link.send_to_drone(drone.drone_id, "mission", message.to_dict())
    _log(drone, user, "stopchain", message.request_id, {"mission_id": mission_id})
    return {"mission_id": mission_id, "status": "sent"}


def _log(drone: Drone, user: Any, command: str, request_id: str, params: dict) -> None:
    CommandLog.objects.create(
        drone=drone,
        user=user,
        request_id=request_id,
        command=command,
        params=params,
        outcome=CommandLog.Outcome.OK,
        response={"status": "sent"},
        answered_at=timezone.now(),
    )

"""Operator pause and resume of a running mission: its drones hold where they are, then
carry on from the step each was on (docs/protocol.md, mission pause and resume)."""

from __future__ import annotations

from typing import Any

from django.db import transaction

from missions.models import Assignment, Event, Mission, MissionStatus
from missions.services import MissionError, record
from onboard import protocol
from workers import outbox


def send_pause(drone_id: str, mission_id: str, action: str) -> None:
    message = protocol.mission_pause(mission_id, action).to_dict()
    outbox.send_to_drone(drone_id, "mission", {**message, "ts": protocol.now()})


def pause(mission: Mission, *, user: Any = None) -> Mission:
    """Hold every drone flying the mission; 409 unless it is running and not paused."""
    return _switch(mission, "pause", user)


def resume(mission: Mission, *, user: Any = None) -> Mission:
    """Let every drone of a paused mission carry on; 409 unless it was paused."""
    return _switch(mission, "resume", user)


def _switch(mission: Mission, action: str, user: Any) -> Mission:
    pausing = action == "pause"
    with transaction.atomic():
        mission = Mission.objects.select_for_update().get(pk=mission.pk)
        if mission.status != MissionStatus.RUNNING:
            raise MissionError("status", f"the mission is {mission.status}, not running", 409)
        if mission.held == pausing:
            state = "already paused" if pausing else "not paused"
            raise MissionError("status", f"the mission is {state}", 409)
        mission.held = pausing
        mission.save(update_fields=["held"])
        drones = list(
            mission.assignments.filter(
                status__in=(Assignment.Status.SENT, Assignment.Status.ACCEPTED)
            ).values_list("drone__drone_id", flat=True)
        )
        record(
            mission,
            Event.Kind.OPERATOR,
            f"mission {'paused: the drones hold' if pausing else 'resumed'}",
            data={
                "action": action,
                "user": getattr(user, "username", None),
                "drones": sorted(set(drones)),
            },
        )
        for drone_id in sorted(set(drones)):
            transaction.on_commit(lambda d=drone_id: send_pause(d, str(mission.pk), action))
    return mission

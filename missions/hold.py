"""Operator pause and resume of a running mission: its drones hold where they are, then
carry on from the step each was on (docs/protocol.md, mission pause and resume).

Holding is per drone: each assignment has its own `held` state, set here (the whole
mission, or one `drone`) and by the drone's own paused / resumed reports (its page's Hold;
missions.progress). The mission's `held` is the operator's Pause of the whole mission.
"""

from __future__ import annotations

from typing import Any

from django.db import transaction

from missions.errors import MissionError
from missions.journal import record
from missions.models import Assignment, Event, Mission, MissionStatus
from onboard import protocol
from workers import outbox

# The assignments a pause or resume reaches: sent to their drone and not finished.
FLYING = (Assignment.Status.SENT, Assignment.Status.ACCEPTED)


def send_pause(drone_id: str, mission_id: str, action: str) -> None:
    message = protocol.mission_pause(mission_id, action).to_dict()
    outbox.send_to_drone(drone_id, "mission", {**message, "ts": protocol.now()})


def pause(mission: Mission, *, user: Any = None, drone: str | None = None) -> Mission:
    """Hold every drone flying the mission, or only `drone` (a drone id); 409 unless it is
    running and the drone (or the mission) is not held already."""
    return _switch(mission, "pause", user, drone)


def resume(mission: Mission, *, user: Any = None, drone: str | None = None) -> Mission:
    """Let every held drone of the mission carry on, or only `drone`; 409 unless held."""
    return _switch(mission, "resume", user, drone)


def _switch(mission: Mission, action: str, user: Any, drone: str | None) -> Mission:
    pausing = action == "pause"
    with transaction.atomic():
        mission = Mission.objects.select_for_update().get(pk=mission.pk)
        if mission.status != MissionStatus.RUNNING:
            raise MissionError("status", f"the mission is {mission.status}, not running", 409)
        flying = list(
            mission.assignments.select_for_update(of=("self",))
            .filter(status__in=FLYING)
            .select_related("drone")
        )
        if drone is None:
            reached = _whole_mission(mission, flying, pausing)
        else:
            reached = _one_drone(mission, flying, pausing, drone)
        Assignment.objects.filter(pk__in=[a.pk for a in reached]).update(held=pausing)
        drones = sorted({a.drone.drone_id for a in reached})
        who = "the drones hold" if drone is None else f"{drone} holds"
        record(
            mission,
            Event.Kind.OPERATOR,
            f"mission {f'paused: {who}' if pausing else 'resumed'}"
            + ("" if drone is None else f" ({drone})"),
            data={"action": action, "user": getattr(user, "username", None), "drones": drones},
        )
        for drone_id in drones:
            transaction.on_commit(lambda d=drone_id: send_pause(d, str(mission.pk), action))
    return mission


def _whole_mission(mission: Mission, flying: list[Assignment], pausing: bool) -> list[Assignment]:
    """Pause: every drone not holding yet. Resume: every drone holding (all of them after a
    mission Pause)."""
    if pausing and mission.held:
        raise MissionError("status", "the mission is already paused", 409)
    held = [a for a in flying if a.held]
    if not pausing and not mission.held and not held:
        raise MissionError("status", "the mission is not paused", 409)
    mission.held = pausing
    mission.save(update_fields=["held"])
    if pausing:
        return [a for a in flying if not a.held]
    return flying if held == [] else held


def _one_drone(
    mission: Mission, flying: list[Assignment], pausing: bool, drone_id: str
) -> list[Assignment]:
    """Only `drone_id`'s assignment; the mission is no longer paused once none holds."""
    mine = [a for a in flying if a.drone.drone_id == drone_id]
    if not mine:
        raise MissionError("drone", f"{drone_id} is not flying this mission", 409)
    # The mission's Pause holds every one of its drones, whatever their own state says.
    if all((a.held or mission.held) == pausing for a in mine):
        state = "already holding" if pausing else "not holding"
        raise MissionError("drone", f"{drone_id} is {state}", 409)
    others_held = any(a.held for a in flying if a not in mine)
    if not pausing and mission.held and not others_held:
        mission.held = False
        mission.save(update_fields=["held"])
    return mine

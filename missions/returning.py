"""The operator's `return` to a drone flying a mission: its part of the mission is stopped
first, so the mission never sends it on while it goes home or holds in the landing queue
(docs/airspace.md, "Landing queue over home").

Called by the landing queue (settings.AIRSPACE_RETURN_STOPS_MISSION) inside the transaction
that sends the drone home, so a return refused changes nothing:

- every active part of the drone (sent, accepted, or queued behind them) on a running or
  paused mission is stopped, with one operator event per mission naming how it goes home;
- the drone is told to stop (after the commit): with `then: return` when it goes home as
  before (the `return` does the same; either one arriving alone is enough), holding where
  it is when it holds over home instead (the queue sends its hold once the drone reports
  no mission running: airspace/landing.py);
- a mission with no other part left to fly is stopped; one whose other drones fly on goes
  on with them.
"""

from __future__ import annotations

from collections.abc import Mapping

from django.db import transaction

from fleet.models import Drone
from missions.journal import move_mission, record
from missions.models import Assignment, Event, Mission, MissionStatus
from missions.sending import send_stop

FLYING = (Assignment.Status.SENT, Assignment.Status.ACCEPTED)


def how_home(queue: Mapping | None) -> str:
    """How the drone goes home, in the mission's words."""
    if queue is None:
        return "home as before (its landing site is free)"
    return (
        f"to hold over home at {queue['layer_m']:g} m, place {queue['place']} in the landing queue"
    )


def stop_for_return(drone: Drone, queue: Mapping | None) -> list[str]:
    """Stop every active part of the drone before it is sent home; `queue` is its place in
    the landing queue (Queued.as_result), None when it goes home as before. The missions
    whose part the drone was flying (it is sent their stop)."""
    parts = list(
        Assignment.objects.select_for_update(of=("self",))
        .filter(
            drone=drone,
            status__in=Assignment.ACTIVE,
            mission__status__in=(MissionStatus.RUNNING, MissionStatus.PAUSED),
        )
        .select_related("mission")
        .order_by("created_at")
    )
    by_mission: dict[str, list[Assignment]] = {}
    for part in parts:
        by_mission.setdefault(str(part.mission_id), []).append(part)
    flown = []
    for mission_id, own in by_mission.items():
        if _stop_parts(own[0].mission, drone, own, queue):
            flown.append(mission_id)
    return flown


def _stop_parts(
    mission: Mission, drone: Drone, own: list[Assignment], queue: Mapping | None
) -> bool:
    flying = any(part.status in FLYING for part in own)
    for part in own:
        part.transition(Assignment.Status.STOPPED)
        part.save(update_fields=["status"])
    record(
        mission,
        Event.Kind.OPERATOR,
        f"{drone.drone_id}'s part stopped: the operator sent it {how_home(queue)}",
        drone=drone,
        data={
            "decision": "returned",
            "assignments": [str(part.pk) for part in own],
            "queue": dict(queue) if queue is not None else None,
        },
    )
    if flying:
        then = "return" if queue is None else None
        drone_id, mission_id = drone.drone_id, str(mission.pk)
        transaction.on_commit(lambda: send_stop(drone_id, mission_id, then=then))
    if not mission.assignments.filter(status__in=Assignment.ACTIVE).exists():
        if move_mission(mission, MissionStatus.STOPPED):
            record(
                mission,
                Event.Kind.DECISION,
                f"mission stopped: no drone flies it after {drone.drone_id} was sent home",
                data={"decision": "stopped_by_return"},
            )
    return flying

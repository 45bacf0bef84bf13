"""The panic button: the nearest available drone arms, climbs to 10 m ([Paula 2018], §5.1),
flies to the caller and stays there "on station": the call runs until the caller or an
operator releases it (the drone returns home, lands and disarms; the call is completed).
A drone whose battery is down to the reserve on station is relieved: the replacement sends
another drone to the caller, as for a CRITICAL alarm, and this one returns home and lands."""

from __future__ import annotations

import logging
import time
from typing import Any

import psycopg
from django.conf import settings
from django.db import OperationalError, transaction

from fleet.models import Organisation
from missions.creation import create_mission
from missions.errors import MissionError
from missions.journal import move_mission, record
from missions.models import Assignment, Event, Mission, MissionStatus
from missions.progress import lock_mission
from missions.sending import stop_and_send_home
from missions.startstop import Started, start_mission
from onboard import protocol

log = logging.getLogger(__name__)

NAME = "Panic call at"
# On station: the longest sleep a step may ask for (docs/protocol.md); a release ends it.
STATION_S = 86400.0


def panic_steps(lat: float, lon: float, altitude: float) -> list[dict]:
    return [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": altitude}},
        # Climb first, then fly: each stage is timed on its own ([Paula 2018], figure 5.8).
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": lat, "lon": lon}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "sleep", "params": {"value": STATION_S}},
    ]


def call_drone(
    *, organisation: Organisation, lat: Any, lon: Any, user: Any = None, confirmed: bool = False
) -> Started:
    """Create and start a panic mission to the caller's position; a caller beyond the
    envelope's defaults from the drone needs `confirmed`."""
    try:
        lat = protocol.latitude(lat, "lat")
        lon = protocol.longitude(lon, "lon")
    except protocol.ProtocolError as exc:
        raise MissionError(exc.field, exc.message) from None
    altitude = settings.MISSIONS_PANIC_ALTITUDE
    mission = create_mission(
        organisation=organisation,
        name=f"{NAME} {lat:.5f}, {lon:.5f}",
        steps=panic_steps(lat, lon, altitude),
        altitude=altitude,
        user=user,
        confirmed=confirmed,
    )
    try:
        # The platform picks the drone: its automatic checklist items, not a person's.
        return start_mission(mission, user=user, confirmed=confirmed, automatic=True)
    except MissionError:
        mission.delete()
        raise


def release(mission: Mission, *, user: Any = None) -> Mission:
    """End a panic call: its drone leaves the station, returns home and lands; the call is
    completed."""
    if not mission.name.startswith(NAME):
        raise MissionError("mission", "only a panic call is released; stop other missions", 409)
    with transaction.atomic():
        mission = Mission.objects.select_for_update().get(pk=mission.pk)
        if mission.status != MissionStatus.RUNNING:
            raise MissionError("status", f"the call is already {mission.status}", 409)
        active = list(
            mission.assignments.filter(status__in=Assignment.ACTIVE).select_related("drone")
        )
        mission.assignments.filter(pk__in=[a.pk for a in active]).update(
            status=Assignment.Status.COMPLETED
        )
        move_mission(mission, MissionStatus.COMPLETED)
        flying = [a.drone for a in active if a.status != Assignment.Status.QUEUED]
        drones = [d.drone_id for d in flying]
        record(
            mission,
            Event.Kind.OPERATOR,
            "panic call released: the drone returns home and lands",
            data={"user": getattr(user, "username", None), "drones": drones},
        )
        for drone in flying:
            # Home through its landing site's queue (airspace/landing.py).
            stop_and_send_home(drone, str(mission.pk))
    return mission


def relieve_stations() -> list[str]:
    """Panic calls whose drone is down to the battery reserve on station: each handed to
    another drone (missions.replacement) once. The relieved drones' ids."""
    from missions import replacement

    low = Assignment.objects.filter(
        status__in=Assignment.ACTIVE,
        mission__status=MissionStatus.RUNNING,
        mission__name__startswith=NAME,
        drone__battery_remaining__lte=settings.MISSIONS_BATTERY_RESERVE,
    ).select_related("mission", "drone")
    relieved = []
    for assignment in low:
        with transaction.atomic():
            lock_mission(assignment.mission)
            event = _record_reserve(assignment)
        if event is not None:
            # It returns home to land: landing on station would put it down by the caller.
            _retrying_deadlocks(
                lambda a=assignment, e=event: replacement.replace_drone(
                    mission_id=str(a.mission_id),
                    assignment_id=str(a.pk),
                    alarm_event_id=e.pk,
                    then="return",
                )
            )
            relieved.append(assignment.drone.drone_id)
    return relieved


DEADLOCK_ATTEMPTS = 3


def _retrying_deadlocks(run: Any) -> None:
    """Run `run` again when PostgreSQL ended it to break a deadlock (it kept nothing of the
    ended transaction, and the replacement is idempotent), as PostgreSQL's manual asks of
    applications; after DEADLOCK_ATTEMPTS the error stands."""
    for attempt in range(1, DEADLOCK_ATTEMPTS + 1):
        try:
            run()
            return
        except OperationalError as exc:
            if attempt == DEADLOCK_ATTEMPTS or not isinstance(
                exc.__cause__, psycopg.errors.DeadlockDetected
            ):
                raise
            log.warning("a replacement met a deadlock; trying again (%d)", attempt)


def _record_reserve(assignment: Assignment) -> Event | None:
    """The decision to relieve the drone, or None when it was already taken."""
    mission, drone = assignment.mission, assignment.drone
    if mission.events.filter(
        data__decision="station_reserve", data__assignment=str(assignment.pk)
    ).exists():
        return None
    position = None if drone.lat is None else {"lat": drone.lat, "lon": drone.lon, "alt": drone.alt}
    return record(
        mission,
        Event.Kind.DECISION,
        f"{drone.drone_id} is down to the battery reserve on station; another drone takes over",
        drone=drone,
        data={
            "decision": "station_reserve",
            "assignment": str(assignment.pk),
            "battery": drone.battery_remaining,
            "position": position,
            "received_at": time.time(),
        },
    )

"""Alarms from `<id>/alarms/out`: recorded, then a replacement or a collaboration enqueued."""

from __future__ import annotations

import time

from django.db import transaction

from fleet.models import Drone
from missions import tasks
from missions.journal import already_recorded, message_key, record
from missions.models import Assignment, Event, Mission, MissionStatus
from missions.progress import find_assignment, find_mission, lock_mission, position_dict
from missions.sending import send_alarm_ack
from missions.signals import critical_alarm_outside_mission
from onboard import protocol


def _active_assignment(drone: Drone) -> Assignment | None:
    return (
        Assignment.objects.filter(
            drone=drone,
            status__in=Assignment.ACTIVE,
            mission__status__in=(MissionStatus.RUNNING, MissionStatus.PAUSED),
        )
        .select_related("mission")
        .order_by("-created_at")
        .first()
    )


def apply_alarm(drone: Drone, alarm: protocol.Alarm) -> str | None:
    """Record the alarm on its mission and enqueue what it asks for; None when taken.

    A CRITICAL alarm is acknowledged to the drone (which repeats it until then,
    onboard.failsafe) once the ground has decided on it: recorded with its task queued,
    or refused. A copy of an alarm already recorded (a redelivery, a retry after an
    outage) records and queues nothing, and is acknowledged again.
    """
    reason = _record_alarm(drone, alarm)
    if alarm.level == "CRITICAL":
        send_alarm_ack(drone.drone_id, alarm.level)
    return reason


def _alarm_assignment(
    drone: Drone, alarm: protocol.Alarm
) -> tuple[Mission | None, Assignment | None, str | None]:
    """The alarm's mission and assignment, or why there is none to record it on."""
    if alarm.mission_id is not None:
        mission = find_mission(drone, alarm.mission_id)
        if mission is None:
            return None, None, "unknown_mission"
        assignment = find_assignment(mission, drone, alarm.assignment_id)
        if assignment is None:
            assignment = _active_assignment(drone)
            if assignment is not None and assignment.mission_id != mission.pk:
                assignment = None
        return mission, assignment, None
    # The fail-safe may fire between steps; the drone's current assignment is meant.
    assignment = _active_assignment(drone)
    if assignment is None:
        return None, None, "alarm_outside_mission"
    return assignment.mission, assignment, None


def _record_alarm(drone: Drone, alarm: protocol.Alarm) -> str | None:
    received_at = time.time()
    mission, assignment, reason = _alarm_assignment(drone, alarm)
    if mission is None:
        if alarm.level == "CRITICAL":
            critical_alarm_outside_mission.send(sender=None, drone=drone, alarm=alarm)
        return reason
    key = message_key(drone, alarm)
    with transaction.atomic():
        # The mission row first, as every writer does: the event's foreign keys are checked
        # at commit, and a replacement holding the mission (then the drone) meanwhile
        # would otherwise deadlock with this alarm (seen with two gateways).
        lock_mission(mission)
        if already_recorded(mission, key):
            return None
        event = record(
            mission,
            Event.Kind.ALARM,
            f"{alarm.level} from {drone.drone_id}: {alarm.message}",
            drone=drone,
            data={
                "level": alarm.level,
                "message": alarm.message,
                "position": position_dict(alarm.position),
                "index": alarm.index,
                "sensor": alarm.sensor,
                "value": alarm.value,
                "ts": alarm.ts,
                "received_at": received_at,
                "assignment": None if assignment is None else str(assignment.pk),
            },
            key=key,
        )
        if assignment is None:
            return None
        kwargs = {
            "mission_id": str(mission.pk),
            "assignment_id": str(assignment.pk),
            "alarm_event_id": event.pk,
        }
        # Queued before the commit, not on it: a gateway killed in between would leave
        # the alarm on record with nothing deciding on it. Should the broker be away, the
        # alarm is rolled back with it and retried whole. The task waits for the alarm
        # to be committed (missions.tasks).
        if alarm.level == "CRITICAL":
            tasks.replace_drone.delay(**kwargs)
        else:
            tasks.collaborate.delay(**kwargs)
    return None

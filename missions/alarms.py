"""Alarms from `<id>/alarms/out`: recorded, then a replacement or a collaboration enqueued."""

from __future__ import annotations

import time

from django.db import transaction

from fleet.models import Drone
from missions import tasks
from missions.models import Assignment, Event, MissionStatus
from missions.services import (
    find_assignment,
    find_mission,
    lock_mission,
    position_dict,
    record,
    send_alarm_ack,
)
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
    """Record the alarm on its mission and enqueue what it asks for; None when taken."""
    received_at = time.time()
    if alarm.level == "CRITICAL":
        # Acknowledged as soon as it is here, whatever it leads to: the drone repeats it
        # until then (onboard.failsafe).
        send_alarm_ack(drone.drone_id, alarm.level)
    if alarm.mission_id is not None:
        mission = find_mission(drone, alarm.mission_id)
        if mission is None:
            return "unknown_mission"
        assignment = find_assignment(mission, drone, alarm.assignment_id)
        if assignment is None:
            assignment = _active_assignment(drone)
            if assignment is not None and assignment.mission_id != mission.pk:
                assignment = None
    else:
        # The fail-safe may fire between steps; the drone's current assignment is meant.
        assignment = _active_assignment(drone)
        if assignment is None:
            return "alarm_outside_mission"
        mission = assignment.mission
    with transaction.atomic():
        # The mission row first, as every writer does: the event's foreign keys are checked
        # at commit, and a replacement holding the mission (then the drone) meanwhile
        # would otherwise deadlock with this alarm (seen with two gateways).
        lock_mission(mission)
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
        )
        if assignment is None:
            return None
        kwargs = {
            "mission_id": str(mission.pk),
            "assignment_id": str(assignment.pk),
            "alarm_event_id": event.pk,
        }
        # Queued before the commit, not on it: a gateway killed in between would leave
        # the alarm on record with nothing deciding on it, and its redelivery may come
        # too late. The task waits for the alarm to be committed (missions.tasks).
        if alarm.level == "CRITICAL":
            tasks.replace_drone.delay(**kwargs)
        else:
            tasks.collaborate.delay(**kwargs)
    return None

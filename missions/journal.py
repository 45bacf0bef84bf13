"""A mission's record: its events (each drone message recorded once) and its status moves,
each pushed to the mission's pages once the transaction commits."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

from django.db import transaction

from fleet.models import Drone
from missions import eventlog, live
from missions.models import (
    Event,
    IllegalTransition,
    Mission,
)
from onboard import protocol


def record(
    mission: Mission,
    kind: str,
    message: str,
    *,
    drone: Drone | None = None,
    data: Mapping | None = None,
    push: bool = True,
    key: str | None = None,
) -> Event:
    """`key` (`message_key`): the drone message recorded, so it is never recorded twice."""
    event = Event.objects.create(
        mission=mission,
        drone=drone,
        kind=kind,
        message=message[:300],
        data=dict(data or {}),
        message_key=key or "",
    )
    if kind == Event.Kind.ALARM:
        eventlog.note(f"alarm, mission {mission.name!r}: {event.message}")
    if push:
        payload = event_payload(event)
        transaction.on_commit(lambda: live.push(mission.pk, payload))
    return event


def message_key(drone: Drone, message: Any) -> str:
    """What identifies a drone's progress report or alarm: its drone, kind, own fields and
    timestamp. The same message delivered twice (a QoS 1 redelivery, a retry through an
    outage) has the same key; a repeated alarm carries a new timestamp."""
    if isinstance(message, protocol.StepProgress):
        kind, fields = "step", (message.assignment_id, message.index, message.status)
    elif isinstance(message, protocol.MissionProgress):
        kind, fields = "mission", (message.assignment_id, message.status)
    else:
        # A drone raises one alarm of a level at a time: a copy rebuilt from the record
        # (with the assignment the ground resolved) is still the same alarm.
        kind, fields = "alarm", (message.level,)
    text = repr((drone.drone_id, *fields, message.ts))
    return f"{kind}:{hashlib.sha256(text.encode()).hexdigest()[:48]}"


def already_recorded(mission: Mission, key: str) -> bool:
    """True when the message of `key` is on record (call with the mission locked)."""
    return Event.objects.filter(mission=mission, message_key=key).exists()


def event_payload(event: Event) -> dict:
    """An event as the mission's websocket carries it; `id` tells a replay from a new one."""
    return {
        "type": "event",
        "id": event.pk,
        "kind": event.kind,
        "message": event.message,
        "drone": event.drone.drone_id if event.drone else None,
        "at": event.at.isoformat(),
        "data": event.data,
    }


def move_mission(mission: Mission, new: str) -> bool:
    """Compare-and-set the mission's status; False if another process moved it first."""
    old = mission.status
    try:
        mission.transition(new)
    except IllegalTransition:
        return False
    changed = Mission.objects.filter(pk=mission.pk, status=old).update(
        status=new, started_at=mission.started_at, ended_at=mission.ended_at
    )
    if changed:
        transaction.on_commit(lambda: live.push(mission.pk, {"type": "mission", "status": new}))
        eventlog.note(f"mission {mission.name!r} ({mission.pk}) {new}")
    else:
        mission.refresh_from_db()
    return bool(changed)

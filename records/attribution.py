"""Who flew a flight and under which mission, and what happened during it.

- A flight armed by a mission step flies that mission (the heartbeat at arming names it,
  else the drone's assignment sent shortly before). Its pilot is whoever started the
  mission (the start decision's user, else the mission's author); a replacement's or a
  collaboration's assignment, or a panic call, is the platform's own work.
- A flight armed by a command (`arm`, or `takeoff`, which arms) has that command's sender
  as its pilot.
- Anything else was armed outside the ground (a radio transmitter): no pilot is known.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.contrib.auth import get_user_model
from django.db.models import Q

from alerts.models import Alert
from fleet.models import CommandLog, ConnectionEvent, Drone
from missions.models import Assignment, Event, Mission
from missions.panic import NAME as PANIC_NAME

from .models import OpenFlight, Origin

ARMING_COMMANDS = ("arm", "takeoff")
PLATFORM_REASONS = (Assignment.Reason.REPLACEMENT, Assignment.Reason.COLLABORATION)
MAX_EVENTS = 200


@dataclass(frozen=True)
class Who:
    origin: str
    pilot: Any = None
    mission: Mission | None = None
    assignment_id: uuid.UUID | None = None


def attribute(flight: OpenFlight, started: datetime) -> Who:
    assignment = _assignment(flight, started)
    if assignment is not None:
        return _mission_pilot(assignment)
    command = _arming_command(flight.drone, started)
    if command is not None and command.user is not None:
        return Who(Origin.COMMAND, pilot=command.user)
    return Who(Origin.UNKNOWN)


def _assignment(flight: OpenFlight, started: datetime) -> Assignment | None:
    named = (
        (flight.mission or {}).get("assignment_id") if isinstance(flight.mission, dict) else None
    )
    if named:
        try:
            found = Assignment.objects.filter(pk=uuid.UUID(str(named)), drone=flight.drone)
        except ValueError:
            found = Assignment.objects.none()
        first = found.select_related("mission").first()
        if first is not None:
            return first
    window = timedelta(seconds=settings.RECORDS_ATTRIBUTION_WINDOW_S)
    return (
        Assignment.objects.filter(
            drone=flight.drone,
            created_at__gte=started - window,
            created_at__lte=started,
            status__in=(*Assignment.ACTIVE, Assignment.Status.COMPLETED),
        )
        .select_related("mission")
        .order_by("-created_at")
        .first()
    )


def _mission_pilot(assignment: Assignment) -> Who:
    mission = assignment.mission
    automatic = assignment.reason in PLATFORM_REASONS or mission.name.startswith(PANIC_NAME)
    if automatic:
        return Who(Origin.PLATFORM, mission=mission, assignment_id=assignment.pk)
    return Who(
        Origin.MISSION,
        pilot=_mission_starter(mission),
        mission=mission,
        assignment_id=assignment.pk,
    )


def _mission_starter(mission: Mission) -> Any:
    start = (
        Event.objects.filter(mission=mission, kind=Event.Kind.DECISION, data__decision="start")
        .order_by("at")
        .first()
    )
    username = (start.data or {}).get("user") if start is not None else None
    if username:
        found = get_user_model().objects.filter(username=username).first()
        if found is not None:
            return found
    return mission.created_by


def _arming_command(drone: Drone, started: datetime) -> CommandLog | None:
    window = timedelta(seconds=settings.RECORDS_ATTRIBUTION_WINDOW_S)
    return (
        CommandLog.objects.filter(
            drone=drone,
            command__in=ARMING_COMMANDS,
            outcome__in=(CommandLog.Outcome.OK, CommandLog.Outcome.PENDING),
            sent_at__gte=started - window,
            sent_at__lte=started + timedelta(seconds=settings.RECORDS_WINDOW_MARGIN_S),
        )
        .select_related("user")
        .order_by("-sent_at")
        .first()
    )


# -- what happened during the flight -------------------------------------------------------


def events(drone: Drone, started: datetime, ended: datetime) -> list[dict]:
    """Alarms (the mission log's), alerts raised for the drone, commands refused by the
    envelope or the drone, and the link going and coming back, in time order; at most
    MAX_EVENTS."""
    found = _mission_events(drone, started, ended)
    found += _alerts(drone, started, ended)
    found += _refused_commands(drone, started, ended)
    found += _link(drone, started, ended)
    found.sort(key=lambda e: e["at"])
    return found[:MAX_EVENTS]


def _kind_of_alarm(message: str) -> str:
    # The drone's envelope guard and its battery fail-safe say so in their alarms
    # (docs/protocol.md, envelope; onboard/failsafe.py).
    if message.startswith("Outside the flight envelope"):
        return "envelope"
    return "failsafe" if message.startswith("battery below") else "alarm"


def _mission_events(drone: Drone, started: datetime, ended: datetime) -> list[dict]:
    rows = Event.objects.filter(
        drone=drone,
        at__gte=started,
        at__lte=ended,
        kind__in=(Event.Kind.ALARM, Event.Kind.HANDOVER),
    ).order_by("at")[:MAX_EVENTS]
    out = []
    for event in rows:
        data = event.data or {}
        kind = _kind_of_alarm(event.message) if event.kind == Event.Kind.ALARM else "handover"
        out.append(
            {
                "at": event.at.isoformat(),
                "kind": kind,
                "level": data.get("level", ""),
                "message": event.message,
                "source": f"mission-event:{event.pk}",
            }
        )
    return out


def _alerts(drone: Drone, started: datetime, ended: datetime) -> list[dict]:
    # Alarms in a mission are in its log already; these are the rest (outside a mission,
    # the drone lost).
    rows = Alert.objects.filter(
        Q(mission_id__isnull=True) | Q(kind=Alert.Kind.DRONE_LOST),
        organisation_id=drone.organisation_id,
        drone_id=drone.drone_id,
        at__gte=started,
        at__lte=ended,
    ).order_by("at")[:MAX_EVENTS]
    return [
        {
            "at": alert.at.isoformat(),
            "kind": "alert",
            "level": alert.severity,
            "message": alert.title,
            "source": f"alert:{alert.pk}",
        }
        for alert in rows
    ]


def _link(drone: Drone, started: datetime, ended: datetime) -> list[dict]:
    """The drone going offline and coming back during the flight: the ground's view of a
    lost link (the drone's own link-loss fail-safe acts meanwhile)."""
    rows = ConnectionEvent.objects.filter(drone=drone, at__gte=started, at__lte=ended).order_by(
        "at"
    )[:MAX_EVENTS]
    return [
        {
            "at": event.at.isoformat(),
            "kind": "link",
            "level": "warning" if event.kind == ConnectionEvent.Kind.OFFLINE else "",
            "message": f"{event.get_kind_display()}: {event.reason}".rstrip(": "),
            "source": f"connection:{event.pk}",
        }
        for event in rows
    ]


def _refused_commands(drone: Drone, started: datetime, ended: datetime) -> list[dict]:
    rows = CommandLog.objects.filter(
        Q(outcome=CommandLog.Outcome.REJECTED) | Q(outcome=CommandLog.Outcome.FAILED),
        drone=drone,
        sent_at__gte=started,
        sent_at__lte=ended,
    ).order_by("sent_at")[:MAX_EVENTS]
    return [
        {
            "at": entry.sent_at.isoformat(),
            "kind": "envelope" if "envelope" in entry.error.lower() else "command_refused",
            "level": "",
            "message": f"{entry.command}: {entry.error}"[:300],
            "source": f"command:{entry.pk}",
        }
        for entry in rows
    ]

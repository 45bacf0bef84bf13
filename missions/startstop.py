"""Starting and stopping missions: the drone a mission starts on (the operator's choice, or
the nearest available), its envelope check, and the stop of every drone flying it; also
`startchain` / `stopchain` on `/control` (named by settings.MISSION_START_STOP_HANDLERS,
which `fleet.commands` calls), tracked as missions."""

from __future__ import annotations

import base64
import binascii
import json
import time
from dataclasses import dataclass
from typing import Any

from django.db import transaction

from airspace import separation
from checklists import gate as checklists
from fleet import envelopes
from fleet.commands import CommandRefused
from fleet.models import Drone
from missions import following
from missions.creation import create_mission
from missions.errors import MissionError, outside_envelope
from missions.journal import move_mission, record
from missions.models import Assignment, Event, Mission, MissionStatus
from missions.selection import check_chosen, first_target, nearest_available
from missions.sending import send_assignment, send_stop, step_dicts


@dataclass(frozen=True)
class Started:
    mission: Mission
    assignment: Assignment
    select_ms: float


def start_mission(
    mission: Mission,
    *,
    drone: Drone | None = None,
    user: Any = None,
    confirmed: bool = False,
    automatic: bool = False,
) -> Started:
    """Give every step to one drone (the chosen one, or the nearest available) and send.

    Steps beyond the envelope's defaults, flown from that drone, need `confirmed`. A person's
    start needs the drone's passed checklist (checklists/gate.py); `automatic` work (a panic
    call) meets the checklists' automatic items in the drone's selection instead.
    """
    began = time.perf_counter()
    with transaction.atomic():
        mission = Mission.objects.select_for_update().get(pk=mission.pk)
        if mission.status != MissionStatus.DRAFT:
            raise MissionError("status", f"the mission is {mission.status}, not a draft", 409)
        steps = list(mission.steps.order_by("index"))
        if not steps:
            raise MissionError("steps", "the mission has no steps")
        plain = step_dicts(steps)
        drone, how = _starting_drone(
            mission, drone, plain, by_person=user is not None and not automatic
        )
        following.check_start_home(mission.extensibility, drone.drone_id, envelopes.home_of(drone))
        try:
            envelopes.check_steps(drone, plain, fence=mission.fence)
            if not confirmed:
                envelopes.confirm_steps(mission.organisation, plain, drone)
            separation.check_mission(drone, plain)
        except envelopes.EnvelopeRefusal as exc:
            raise outside_envelope(exc) from None
        envelopes.forget_target(drone)
        assignment = Assignment.objects.create(
            mission=mission,
            drone=drone,
            step_indexes=[s.index for s in steps],
            reason=Assignment.Reason.INITIAL,
            status=Assignment.Status.SENT,
        )
        move_mission(mission, MissionStatus.RUNNING)
        select_ms = (time.perf_counter() - began) * 1000
        record(
            mission,
            Event.Kind.DECISION,
            f"{drone.drone_id} starts the mission ({how})",
            drone=drone,
            data={
                "decision": "start",
                "assignment": str(assignment.id),
                "drone_id": drone.drone_id,
                "how": how,
                "select_ms": round(select_ms, 3),
                "user": getattr(user, "username", None),
            },
        )
        transaction.on_commit(lambda: send_assignment(assignment))
    return Started(mission, assignment, select_ms)


def _starting_drone(
    mission: Mission, drone: Drone | None, plain: list, *, by_person: bool
) -> tuple[Drone, str]:
    """The drone the mission starts on, checked, and how it was chosen; a start by a person
    needs its passed pre-flight checklist."""
    how = "chosen by the operator"
    if drone is not None:
        check_chosen(mission, drone)
    else:
        found = nearest_available(mission.organisation_id, target=first_target(plain))
        if not found:
            raise MissionError(
                "drone", "no drone is available (online, free, charged, airworthy)", 409
            )
        drone, how = found[0], "nearest available"
    not_checked = checklists.refusal(drone) if by_person else None
    if not_checked is not None:
        raise MissionError("drone", not_checked, 409, "checklist_required")
    return drone, how


def stop_mission(
    mission: Mission, *, user: Any = None, reason: str = "stopped by the operator"
) -> Mission:
    """Stop every drone flying the mission (stopchain) and mark it stopped."""
    with transaction.atomic():
        mission = Mission.objects.select_for_update().get(pk=mission.pk)
        if mission.status not in (MissionStatus.RUNNING, MissionStatus.PAUSED, MissionStatus.DRAFT):
            raise MissionError("status", f"the mission is already {mission.status}", 409)
        active = list(
            mission.assignments.filter(status__in=Assignment.ACTIVE).select_related("drone")
        )
        mission.assignments.filter(status__in=Assignment.ACTIVE).update(
            status=Assignment.Status.STOPPED
        )
        move_mission(mission, MissionStatus.STOPPED)
        record(
            mission,
            Event.Kind.OPERATOR,
            reason,
            data={
                "user": getattr(user, "username", None),
                "drones": [a.drone.drone_id for a in active],
            },
        )
        for assignment in active:
            if assignment.status != Assignment.Status.QUEUED:
                drone_id = assignment.drone.drone_id
                transaction.on_commit(lambda d=drone_id: send_stop(d, str(mission.pk)))
    return mission


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
        raise CommandRefused(exc.status, exc.message, exc.field, exc.code, exc.reasons) from None
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

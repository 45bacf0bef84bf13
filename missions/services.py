"""Mission execution: create, start, stop, and apply progress.

Plain functions over the models. Views, the gateway handlers, Celery tasks and the
`/control` chain hooks call them. Messages to drones go through the gateway's Redis
outbox (`workers.outbox`), always after the transaction that recorded them commits, so a
progress report can never arrive for a row that is not there yet.
"""

from __future__ import annotations

import hashlib
import logging
import time
import uuid
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from django.conf import settings
from django.db import transaction
from django.utils import timezone

from fleet import envelopes
from fleet.models import Drone, Organisation
from missions import eventlog, live
from missions.models import (
    STEP_DONE,
    Assignment,
    Event,
    IllegalTransition,
    Mission,
    MissionStatus,
    Step,
    StepStatus,
)
from missions.selection import Candidate, select_drones
from onboard import protocol
from workers import outbox

log = logging.getLogger(__name__)

MAX_STEPS = 100_000


class MissionError(ValueError):
    """A request the domain refuses; `field` names the input, `status` the HTTP answer."""

    def __init__(
        self, field: str, message: str, status: int = 400, code: str | None = None
    ) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
        self.status = status
        self.code = code


def outside_envelope(exc: envelopes.EnvelopeRefusal) -> MissionError:
    """The 409 for a mission step the envelope refuses, or that goes beyond its defaults
    unconfirmed (nothing is sent)."""
    return MissionError("steps", exc.message, 409, exc.code)


# ---------------------------------------------------------------------------------------
# Creating missions.


def validate_steps(raw_steps: Any) -> list[dict]:
    """Steps as the API receives them → mission steps, indexes 0..n-1 in list order.

    An `index` given by the client must equal its position (the mission's index space is
    dense); commands and params are checked with the drone's own rules.
    """
    if not isinstance(raw_steps, list):
        raise MissionError("steps", "must be a list of steps")
    if not raw_steps:
        raise MissionError("steps", "a mission needs at least one step")
    if len(raw_steps) > MAX_STEPS:
        raise MissionError("steps", f"at most {MAX_STEPS} steps")
    steps = []
    for position, raw in enumerate(raw_steps):
        if isinstance(raw, Mapping) and "index" not in raw:
            raw = {**raw, "index": position}
        try:
            step = protocol.parse_step(raw, f"steps[{position}]")
        except protocol.ProtocolError as exc:
            raise MissionError(exc.field, exc.message) from None
        if step.index != position:
            raise MissionError(
                f"steps[{position}].index", f"must be {position} (steps are numbered in order)"
            )
        steps.append(step.to_dict())
    return steps


def create_mission(
    *,
    organisation: Organisation,
    name: str,
    steps: Any,
    altitude: float = 10.0,
    extensibility: Mapping | None = None,
    user: Any = None,
    home: Sequence[float] | None = None,
    fence: Mapping | None = None,
    confirmed: bool = False,
) -> Mission:
    """A draft mission with validated steps (nothing is sent until `start_mission`).

    The steps must keep to the organisation's envelope, and to `fence` (an imported
    plan's own geoFence), flown from `home` (a plan's home; else fleet.envelopes.plan_home);
    steps beyond the envelope's defaults need `confirmed`.
    """
    clean = validate_steps(steps)
    try:
        envelopes.check_plan(organisation, clean, home, fence)
        if not confirmed:
            envelopes.confirm_steps(organisation, clean, home=home)
    except envelopes.EnvelopeRefusal as exc:
        raise outside_envelope(exc) from None
    name = (name or "").strip() or f"Mission {timezone.now():%Y-%m-%d %H:%M}"
    with transaction.atomic():
        mission = Mission.objects.create(
            organisation=organisation,
            name=name[:200],
            altitude=altitude,
            extensibility=dict(extensibility) if extensibility else None,
            created_by=user if getattr(user, "is_authenticated", False) else None,
            fence=dict(fence)
            if fence and (fence.get("polygons") or fence.get("circles"))
            else None,
            plan_home=list(home) if home is not None else None,
        )
        Step.objects.bulk_create(
            Step(mission=mission, index=s["index"], command=s["command"], params=s["params"])
            for s in clean
        )
    return mission


# ---------------------------------------------------------------------------------------
# Choosing drones.


def busy_drone_ids(organisation_id: int) -> set[str]:
    """Drones holding an unfinished assignment of a running or paused mission."""
    return set(
        Assignment.objects.filter(
            drone__organisation_id=organisation_id,
            status__in=Assignment.ACTIVE,
            mission__status__in=(MissionStatus.RUNNING, MissionStatus.PAUSED),
        ).values_list("drone__drone_id", flat=True)
    )


def candidates(organisation_id: int) -> list[Candidate]:
    busy = busy_drone_ids(organisation_id)
    out = []
    for drone in Drone.objects.filter(organisation_id=organisation_id, credentials_revoked=False):
        position = None if drone.lat is None or drone.lon is None else (drone.lat, drone.lon)
        out.append(
            Candidate(
                drone_id=drone.drone_id,
                online=drone.online,
                in_mission=drone.drone_id in busy,
                battery=drone.battery_remaining,
                position=position,
            )
        )
    return out


def nearest_available(
    organisation_id: int,
    *,
    target: tuple[float, float] | None,
    count: int = 1,
    exclude: Sequence[str] = (),
) -> list[Drone]:
    """Up to `count` available drones of the organisation, nearest to `target` first."""
    pool = candidates(organisation_id)
    if target is None:
        # Nothing to fly to: any place among the drones will do; battery then decides.
        placed = [c.position for c in pool if c.position is not None]
        if not placed:
            return []
        target = placed[0]
    chosen = select_drones(
        pool,
        target=target,
        count=count,
        reserve=settings.MISSIONS_BATTERY_RESERVE,
        exclude=exclude,
    )
    by_id = {d.drone_id: d for d in Drone.objects.filter(drone_id__in=[c.drone_id for c in chosen])}
    return [by_id[c.drone_id] for c in chosen]


def first_target(steps: Iterable[Mapping]) -> tuple[float, float] | None:
    for step in steps:
        if step["command"] == "navigate":
            return float(step["params"]["lat"]), float(step["params"]["lon"])
    return None


def _check_chosen(mission: Mission, drone: Drone) -> None:
    if drone.organisation_id != mission.organisation_id:
        raise MissionError("drone", f"no drone {drone.drone_id!r} in this organisation", 404)
    pool = {c.drone_id: c for c in candidates(mission.organisation_id)}
    candidate = pool[drone.drone_id]
    if not candidate.online:
        raise MissionError("drone", f"drone {drone.drone_id} is offline", 409)
    if candidate.in_mission:
        raise MissionError("drone", f"drone {drone.drone_id} is flying another mission", 409)
    reserve = settings.MISSIONS_BATTERY_RESERVE
    if candidate.battery is None or candidate.battery <= reserve:
        raise MissionError(
            "drone", f"drone {drone.drone_id} has not reported a battery above {reserve:.0%}", 409
        )


# ---------------------------------------------------------------------------------------
# Sending to drones.


def step_dicts(steps: Iterable[Step]) -> list[dict]:
    return [{"index": s.index, "command": s.command, "params": s.params} for s in steps]


def send_assignment(assignment: Assignment) -> None:
    """Publish the assignment's steps (preparation first, then its mission steps)."""
    indexes = list(assignment.preparation) + list(assignment.step_indexes)
    by_index = {
        s.index: s for s in Step.objects.filter(mission_id=assignment.mission_id, index__in=indexes)
    }
    steps = step_dicts(by_index[i] for i in indexes)
    message = protocol.mission_start(str(assignment.mission_id), str(assignment.id), steps)
    # Its issue time: a drone refuses a start queued too long while it was away.
    outbox.send_to_drone(
        assignment.drone.drone_id,
        "mission",
        {**message.to_dict(), "ts": protocol.now()},
        ttl=settings.MISSIONS_START_TTL_S,
    )
    if Mission.objects.filter(pk=assignment.mission_id, held=True).exists():
        # A drone sent to a paused mission (a replacement) holds as the others do.
        pause = protocol.mission_pause(str(assignment.mission_id), "pause").to_dict()
        outbox.send_to_drone(assignment.drone.drone_id, "mission", pause)


def send_stop(drone_id: str, mission_id: str, then: str | None = None) -> None:
    """Stop the drone's mission; `then` (protocol.STOP_FOLLOW_UPS) is what it does next,
    holding where it is when not given."""
    message = protocol.MissionStop(protocol.new_request_id(), str(mission_id)).to_dict()
    if then is not None:
        message["then"] = then
    outbox.send_to_drone(drone_id, "mission", message)


def send_alarm_ack(drone_id: str, level: str) -> None:
    """Tell the drone its alarm arrived, so it stops repeating it."""
    outbox.send_to_drone(drone_id, "alarms", protocol.AlarmAck(level).to_dict())


def send_control(drone_id: str, command: str, params: dict | None = None) -> None:
    request = protocol.control_request(command, params or {})
    outbox.send_to_drone(drone_id, "control", request.to_dict())


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


# ---------------------------------------------------------------------------------------
# Start and stop.


@dataclass(frozen=True)
class Started:
    mission: Mission
    assignment: Assignment
    select_ms: float


def start_mission(
    mission: Mission, *, drone: Drone | None = None, user: Any = None, confirmed: bool = False
) -> Started:
    """Give every step to one drone (the chosen one, or the nearest available) and send.

    Steps beyond the envelope's defaults, flown from that drone, need `confirmed`.
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
        if drone is not None:
            _check_chosen(mission, drone)
            how = "chosen by the operator"
        else:
            found = nearest_available(mission.organisation_id, target=first_target(plain))
            if not found:
                raise MissionError("drone", "no drone is available (online, free, charged)", 409)
            drone = found[0]
            how = "nearest available"
        try:
            envelopes.check_steps(drone, plain, fence=mission.fence)
            if not confirmed:
                envelopes.confirm_steps(mission.organisation, plain, drone)
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


# ---------------------------------------------------------------------------------------
# Progress from `<id>/mission/out`.


def find_mission(drone: Drone, mission_id: str) -> Mission | None:
    """The drone's organisation's mission with that id (None for ids we never issued)."""
    try:
        uuid.UUID(str(mission_id))
    except ValueError:
        return None
    return Mission.objects.filter(pk=mission_id, organisation_id=drone.organisation_id).first()


def find_assignment(mission: Mission, drone: Drone, assignment_id: str | None) -> Assignment | None:
    if assignment_id is None:
        return None
    try:
        uuid.UUID(str(assignment_id))
    except ValueError:
        return None
    return Assignment.objects.filter(pk=assignment_id, mission=mission, drone=drone).first()


def position_dict(position: protocol.Position | None) -> dict | None:
    if position is None:
        return None
    return {"lat": position.lat, "lon": position.lon, "alt": position.alt}


def _when(ts: float) -> datetime:
    return datetime.fromtimestamp(ts, tz=UTC)


def apply_progress(
    drone: Drone, message: protocol.MissionProgress | protocol.StepProgress
) -> str | None:
    """Record one progress message; None when taken, else why it was dropped."""
    mission = find_mission(drone, message.mission_id)
    if mission is None:
        return "unknown_mission"
    assignment = find_assignment(mission, drone, message.assignment_id)
    if isinstance(message, protocol.StepProgress):
        return _apply_step(mission, drone, assignment, message)
    return _apply_mission_status(mission, drone, assignment, message)


def lock_mission(mission: Mission) -> None:
    """Every writer locks the mission row first, then its assignments and steps: one
    order everywhere, so a stop, a replacement and progress never deadlock."""
    Mission.objects.select_for_update().filter(pk=mission.pk).values_list("pk", flat=True).first()


_lock = lock_mission


def _apply_step(
    mission: Mission, drone: Drone, assignment: Assignment | None, message: protocol.StepProgress
) -> str | None:
    if assignment is None:
        return "unknown_assignment"
    given = set(assignment.step_indexes) | set(assignment.preparation)
    if message.index not in given:
        return "step_not_assigned"
    position = position_dict(message.position)
    key = message_key(drone, message)
    with transaction.atomic():
        _lock(mission)
        if already_recorded(mission, key):
            _replay_accepted(mission, drone, message)
            return None
        step = Step.objects.select_for_update().filter(mission=mission, index=message.index).first()
        if step is None:
            return "unknown_step"
        # After a handover the old drone's "failed" (it was told to stop) is noise.
        retired = assignment.status in (Assignment.Status.STOPPED, Assignment.Status.REJECTED)
        late = _late_own_report(mission, drone, step, message)
        duplicate = not late and (
            step.status in STEP_DONE or (retired and message.status != StepStatus.COMPLETED)
        )
        if not duplicate and not late:
            try:
                step.transition(message.status)
            except IllegalTransition:
                duplicate = True
        if not duplicate:
            step.drone = drone
            if message.status == StepStatus.STARTED:
                step.started_at = _when(message.ts)
            else:
                step.ended_at = _when(message.ts)
                step.duration_s = message.duration_s
                step.result = message.result or ({"error": message.error} if message.error else {})
            if position is not None:
                step.position = position
            step.save()
        record(
            mission,
            Event.Kind.STEP,
            f"step {message.index} {message.command} {message.status}",
            drone=drone,
            data=_step_data(message, position, assignment, duplicate),
            key=key,
        )
        if message.status == StepStatus.COMPLETED and not duplicate:
            complete_if_done(mission)
        elif duplicate:
            _replay_accepted(mission, drone, message)
    return None


def _step_data(
    message: protocol.StepProgress, position: dict | None, assignment: Assignment, ignored: bool
) -> dict:
    return {
        "index": message.index,
        "command": message.command,
        "status": message.status,
        "ts": message.ts,
        "position": position,
        "duration_s": message.duration_s,
        "result": message.result,
        "error": message.error,
        "assignment": str(assignment.pk),
        "ignored": ignored,
    }


def _replay_accepted(mission: Mission, drone: Drone, message: protocol.StepProgress) -> None:
    """A copy of a report already taken (a QoS 1 redelivery) may come from a process that
    died between committing it and pushing it live: push the accepted event and the
    mission's status again, so the pages still see them. Pages know a replay by its id."""
    accepted = (
        mission.events.filter(
            kind=Event.Kind.STEP,
            drone=drone,
            data__index=message.index,
            data__status=message.status,
            data__ignored=False,
        )
        .select_related("drone")
        .first()
    )
    if accepted is None:
        return
    mission.refresh_from_db(fields=["status"])
    payloads = [event_payload(accepted), {"type": "mission", "status": mission.status}]

    def push() -> None:
        for payload in payloads:
            live.push(mission.pk, payload)

    transaction.on_commit(push)


def _late_own_report(
    mission: Mission, drone: Drone, step: Step, message: protocol.StepProgress
) -> bool:
    """A step's own "completed" arriving after the drone's "mission completed" already
    marked it done. Several gateways share the drones' topics, so one drone's messages
    may be handled out of order; the late report still brings the step's duration and
    result, and is accepted once."""
    if message.status != StepStatus.COMPLETED or step.status != StepStatus.COMPLETED:
        return False
    if step.drone_id != drone.pk:
        return False
    accepted = mission.events.filter(
        kind=Event.Kind.STEP,
        data__index=step.index,
        data__status=StepStatus.COMPLETED,
        data__ignored=False,
    )
    return not accepted.exists()


def _apply_mission_status(
    mission: Mission,
    drone: Drone,
    assignment: Assignment | None,
    message: protocol.MissionProgress,
) -> str | None:
    key = message_key(drone, message)
    with transaction.atomic():
        _lock(mission)
        if already_recorded(mission, key):
            return None
        if assignment is not None:
            assignment = Assignment.objects.select_for_update().get(pk=assignment.pk)
            _move_assignment(assignment, message)
        record(
            mission,
            Event.Kind.MISSION,
            f"{drone.drone_id}: mission {message.status}"
            + (f" ({message.error})" if message.error else ""),
            drone=drone,
            data={
                "status": message.status,
                "ts": message.ts,
                "decode_ms": message.decode_ms,
                "error": message.error,
                "assignment": None if assignment is None else str(assignment.pk),
            },
            key=key,
        )
        if assignment is not None and message.status == "completed":
            # A drone reports its mission completed only after every step succeeded, so
            # a step report lost on the way (gateway restart) is recovered here.
            _complete_steps(mission, drone, assignment)
            complete_if_done(mission)
        if message.status in ("completed", "stopped"):
            # Also without an assignment: a drone told to stop a mission it had already
            # finished answers "stopped" with no assignment id.
            dispatch_queued(mission, drone)
        if assignment is not None and message.status == "rejected":
            _rejected(mission, drone, assignment, message.error)
        if message.status in ("paused", "resumed"):
            _held_reported(mission, drone, message.status == "paused")
    return None


def _held_reported(mission: Mission, drone: Drone, held: bool) -> None:
    """A drone says it holds (its own page's Hold, or a pause it obeyed) or flies on: only
    its own assignment changes, never its companions'. The mission's Pause ends when
    none of its drones holds any more."""
    mission.assignments.filter(drone=drone, status__in=Assignment.ACTIVE).update(held=held)
    flying = (Assignment.Status.SENT, Assignment.Status.ACCEPTED)
    if not held and not mission.assignments.filter(status__in=flying, held=True).exists():
        Mission.objects.filter(pk=mission.pk, held=True).update(held=False)


def _move_assignment(assignment: Assignment, message: protocol.MissionProgress) -> None:
    """Follow the drone's report; a late or repeated one (stopped, then accepted) is noise."""
    try:
        assignment.transition(message.status)
    except IllegalTransition:
        return
    if message.decode_ms is not None:
        assignment.decode_ms = message.decode_ms
    assignment.save(update_fields=["status", "decode_ms"])


def _complete_steps(mission: Mission, drone: Drone, assignment: Assignment) -> None:
    indexes = list(assignment.preparation) + list(assignment.step_indexes)
    missing = mission.steps.filter(index__in=indexes).exclude(status__in=STEP_DONE)
    missing.update(status=StepStatus.COMPLETED, drone=drone, ended_at=timezone.now())


def _rejected(mission: Mission, drone: Drone, assignment: Assignment, error: str | None) -> None:
    """A drone refused its steps: the mission cannot go on without an operator."""
    if mission.assignments.filter(status__in=Assignment.ACTIVE).exists():
        return
    if move_mission(mission, MissionStatus.FAILED):
        record(
            mission,
            Event.Kind.DECISION,
            f"mission failed: {drone.drone_id} rejected its steps ({error or 'no reason'})",
            drone=drone,
            data={"decision": "failed", "assignment": str(assignment.pk), "error": error},
        )


def complete_if_done(mission: Mission) -> bool:
    """Completed when every step is completed (or superseded), whoever did it."""
    mission.refresh_from_db(fields=["status", "started_at", "ended_at"])
    if mission.status not in (MissionStatus.RUNNING, MissionStatus.PAUSED):
        return False
    if mission.steps.exclude(status__in=STEP_DONE).exists():
        return False
    if mission.status == MissionStatus.PAUSED and not move_mission(mission, MissionStatus.RUNNING):
        return False
    if not move_mission(mission, MissionStatus.COMPLETED):
        return False
    record(mission, Event.Kind.DECISION, "every step is completed", data={"decision": "completed"})
    return True


def dispatch_queued(mission: Mission, drone: Drone) -> None:
    """Send the drone's queued assignment once its previous one has ended."""
    queued = (
        mission.assignments.select_for_update()
        .filter(drone=drone, status=Assignment.Status.QUEUED)
        .order_by("created_at")
        .first()
    )
    if queued is None or mission.status not in (MissionStatus.RUNNING, MissionStatus.PAUSED):
        return
    queued.transition(Assignment.Status.SENT)
    queued.save(update_fields=["status"])
    transaction.on_commit(lambda: send_assignment(queued))

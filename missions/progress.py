"""What drones report of their missions (`<id>/mission/out`), applied: steps started,
completed or failed, missions accepted, rejected, paused or ended, each recorded once however
often it is delivered."""

from __future__ import annotations

import uuid
from datetime import UTC, datetime

from django.db import transaction
from django.utils import timezone

from fleet.models import Drone
from missions import live
from missions.collaboration import ready_to_fly
from missions.journal import already_recorded, event_payload, message_key, move_mission, record
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
from missions.sending import send_assignment
from onboard import protocol


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
        ended_itself = False
        if assignment is not None:
            assignment = Assignment.objects.select_for_update().get(pk=assignment.pk)
            # A stop the ground asked for has already moved the assignment; only the
            # drone's own stop moves it here.
            ended_itself = _move_assignment(assignment, message) and message.status == "stopped"
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
        if ended_itself and protocol.failed_step(message.error) is not None:
            _part_failed(mission, drone, assignment, message.error)  # type: ignore[arg-type]
        if message.status in ("completed", "stopped"):
            # Also without an assignment: a drone told to stop a mission it had already
            # finished answers "stopped" with no assignment id.
            dispatch_queued(mission, drone)
            end_if_stranded(mission)
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


def _move_assignment(assignment: Assignment, message: protocol.MissionProgress) -> bool:
    """Follow the drone's report (True when it moved the assignment); a late or repeated
    one (stopped, then accepted) is noise."""
    try:
        assignment.transition(message.status)
    except IllegalTransition:
        return False
    if message.decode_ms is not None:
        assignment.decode_ms = message.decode_ms
    assignment.save(update_fields=["status", "decode_ms"])
    return True


def _part_failed(mission: Mission, drone: Drone, assignment: Assignment, error: str) -> None:
    """The drone stopped its steps itself because one failed (it refused it: not armed,
    outside its envelope): no drone flies the rest of them. Recorded, so that the mission
    ends once nothing else flies (`end_if_stranded`)."""
    index, command, why = protocol.failed_step(error)  # type: ignore[misc]
    record(
        mission,
        Event.Kind.DECISION,
        f"{drone.drone_id} stopped its steps: step {index} ({command}) failed: {why}",
        drone=drone,
        data={"decision": "part_failed", "assignment": str(assignment.pk), "index": index},
    )


def part_not_sent(mission: Mission, assignment: Assignment, why: str) -> None:
    """A queued part that cannot be flown is not sent: stopped, recorded as failed."""
    assignment.transition(Assignment.Status.STOPPED)
    assignment.save(update_fields=["status"])
    record(
        mission,
        Event.Kind.DECISION,
        f"part not sent: {why}",
        drone=assignment.drone,
        data={"decision": "part_failed", "assignment": str(assignment.pk)},
    )


def end_if_stranded(mission: Mission) -> bool:
    """A running mission whose steps are not all done, with no drone left flying any of
    them, after a drone's part failed: it fails, naming why (it never stays running);
    after the operator sent one of its drones home (missions/returning.py): it is
    stopped, naming that."""
    mission.refresh_from_db(fields=["status", "started_at", "ended_at"])
    if mission.status != MissionStatus.RUNNING:
        return False
    if mission.assignments.filter(status__in=Assignment.ACTIVE).exists():
        return False
    if not mission.steps.exclude(status__in=STEP_DONE).exists():
        return False
    cause, status = _stranding_cause(mission)
    if cause is None or not move_mission(mission, status):
        return False
    left = mission.steps.exclude(status__in=STEP_DONE).count()
    record(
        mission,
        Event.Kind.DECISION,
        f"mission {status}: {left} steps left and no drone flies them ({cause.message})",
        data={"decision": status, "steps_left": left, "cause": cause.pk},
    )
    return True


# What ends a stranded mission, in order: a part that failed fails it, a part the operator
# sent home stops it.
_STRANDED_BY = (
    ("part_failed", MissionStatus.FAILED.value),
    ("returned", MissionStatus.STOPPED.value),
)


def _stranding_cause(mission: Mission) -> tuple[Event | None, str]:
    """The latest event of the first kind in _STRANDED_BY, and the status it ends in."""
    for decision, status in _STRANDED_BY:
        cause = mission.events.filter(data__decision=decision).order_by("-pk").first()
        if cause is not None:
            return cause, status
    return None, MissionStatus.FAILED.value


def _complete_steps(mission: Mission, drone: Drone, assignment: Assignment) -> None:
    indexes = list(assignment.preparation) + list(assignment.step_indexes)
    missing = mission.steps.filter(index__in=indexes).exclude(status__in=STEP_DONE)
    missing.update(status=StepStatus.COMPLETED, drone=drone, ended_at=timezone.now())


def _rejected(mission: Mission, drone: Drone, assignment: Assignment, error: str | None) -> None:
    """A drone refused its steps: the mission cannot go on without an operator. While
    other drones still fly it, the refusal is recorded as a failed part: the mission fails
    once they are done (`end_if_stranded`)."""
    if mission.assignments.filter(status__in=Assignment.ACTIVE).exists():
        record(
            mission,
            Event.Kind.DECISION,
            f"{drone.drone_id} rejected its steps ({error or 'no reason'})",
            drone=drone,
            data={"decision": "part_failed", "assignment": str(assignment.pk)},
        )
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
    why_not = ready_to_fly(queued)
    if why_not is not None:
        part_not_sent(mission, queued, why_not)
        return
    queued.transition(Assignment.Status.SENT)
    queued.save(update_fields=["status"])
    transaction.on_commit(lambda: send_assignment(queued))

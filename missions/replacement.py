"""Replacing a drone that must stop, exactly once per failure.

The failing assignment's row lock serialises concurrent runs; the one-to-one
`Assignment.replaces` makes a second replacement of the same failure impossible, so a
duplicated alarm or a task re-run after a worker died (acks late) changes nothing. With
no drone available the mission is paused; `resume_paused` retries from Celery beat.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping

from django.db import transaction

from airspace import separation
from fleet import envelopes
from fleet.models import Drone
from missions.handover import Assignment as PlannedAssignment
from missions.handover import Handover, plan_replacement
from missions.journal import move_mission, record
from missions.models import (
    STEP_DONE,
    Assignment,
    Event,
    Mission,
    MissionStatus,
    Step,
    StepStatus,
)
from missions.planning import PlanningError
from missions.selection import nearest_available
from missions.sending import send_assignment, send_control, send_stop, stop_and_send_home

log = logging.getLogger(__name__)


def planner_view(mission: Mission, own: set[int], done_too: set[int] = frozenset()) -> list[dict]:
    """The mission's steps for the handover planner: only `own` steps may be left to do.

    Steps of other drones (and superseded ones) count as done, so the replacement takes
    over the failing drone's work only, while indexes stay in the mission's index space.
    `done_too` are steps done although their report may still be on its way.
    """
    view = []
    for step in mission.steps.order_by("index"):
        done = step.status in STEP_DONE or step.index not in own or step.index in done_too
        view.append(
            {
                "index": step.index,
                "command": step.command,
                "params": step.params,
                "status": StepStatus.COMPLETED if done else step.status,
            }
        )
    return view


def _stop_position(alarm: Event | None, failing: Assignment) -> tuple[float, float] | None:
    position = (alarm.data.get("position") if alarm else None) or None
    if isinstance(position, Mapping) and position.get("lat") is not None:
        return float(position["lat"]), float(position["lon"])
    drone = failing.drone
    if drone.lat is not None and drone.lon is not None:
        return drone.lat, drone.lon
    return None


def replace_drone(
    *,
    mission_id: str,
    assignment_id: str,
    alarm_event_id: int | None = None,
    then: str = "land",
) -> Assignment | None:
    """Stop the failing drone and land it (`then`: "land" where it is, or "return" home
    first), then hand its remaining steps to the nearest available one; pause the mission
    when there is none. Returns the new assignment."""
    began = time.perf_counter()
    with transaction.atomic():
        mission, failing = _lock(mission_id, assignment_id)
        if mission is None or failing is None:
            return None
        existing = Assignment.objects.filter(replaces=failing).first()
        if existing is not None:
            return _already_replaced(existing)
        if not _replaceable(mission, failing):
            return None
        alarm = Event.objects.filter(pk=alarm_event_id, mission=mission).first()
        _stop_failing(mission, failing, then)
        own = set(failing.step_indexes) | set(failing.preparation)
        view = planner_view(mission, own, _raising_step(mission, alarm))
        stop_position = _stop_position(alarm, failing)
        remaining = [s for s in view if s["status"] != StepStatus.COMPLETED]
        if not remaining:
            _nothing_left(mission, failing)
            return None
        select_began = time.perf_counter()
        drone = _nearest_replacement(
            mission, failing, stop_position or _first_navigation(remaining)
        )
        select_ms = (time.perf_counter() - select_began) * 1000
        if drone is None:
            _pause(mission, failing, stop_position, alarm)
            return None
        plan_began = time.perf_counter()
        handover = _plan_handover(mission, view, stop_position, drone)
        if handover is None:
            return None
        replacement = _commit(mission, failing, drone, handover)
        timings = {
            "select_ms": round(select_ms, 3),
            "plan_ms": round((time.perf_counter() - plan_began) * 1000, 3),
            "task_ms": round((time.perf_counter() - began) * 1000, 3),
        }
        if alarm is not None and alarm.data.get("received_at"):
            timings["since_alarm_ms"] = round((time.time() - alarm.data["received_at"]) * 1000, 3)
        _record_replacement(
            replacement, handover.assignments[0], stop_position, alarm_event_id, timings
        )
        transaction.on_commit(lambda: dispatch(replacement))
    return replacement


def _lock(mission_id: str, assignment_id: str) -> tuple[Mission | None, Assignment | None]:
    """Lock the mission and the failing assignment: concurrent runs for one failure queue here."""
    mission = Mission.objects.select_for_update().filter(pk=mission_id).first()
    failing = (
        # Only the assignment's row: locking the joined drone too would block every
        # event of that drone (their foreign key checks) while we plan.
        Assignment.objects.select_for_update(of=("self",))
        .select_related("drone")
        .filter(pk=assignment_id, mission_id=mission_id)
        .first()
    )
    return mission, failing


def _already_replaced(existing: Assignment) -> Assignment:
    """A second run for the same failure changes nothing but a send that never went."""
    if not _dispatched(existing):
        # A run that died between its commit and the send: send now. Should the
        # first send have gone out after all, the busy drone rejects this one.
        transaction.on_commit(lambda: dispatch(existing))
    return existing


def _replaceable(mission: Mission, failing: Assignment) -> bool:
    """Only a running or paused mission replaces, and only an assignment not yet over."""
    if mission.status not in (MissionStatus.RUNNING, MissionStatus.PAUSED):
        return False
    return failing.status not in (Assignment.Status.COMPLETED, Assignment.Status.REJECTED)


def _stop_failing(mission: Mission, failing: Assignment, then: str = "land") -> None:
    """Tell a drone still flying its assignment to stop and land, where it is or back
    home (after the commit)."""
    if failing.status not in Assignment.ACTIVE:
        return
    failing_id = failing.drone.drone_id
    failing.transition(Assignment.Status.STOPPED)
    failing.save(update_fields=["status"])
    record(
        mission,
        Event.Kind.DECISION,
        f"{failing_id} told to stop and {'return home' if then == 'return' else 'land'}",
        drone=failing.drone,
        data={"decision": "stop_failing", "assignment": str(failing.pk), "then": then},
    )
    if then == "return":
        # Home through its landing site's queue: the stop itself sends it home (return,
        # land, disarm: docs/failsafe.md), or it holds over home for its turn.
        stop_and_send_home(failing.drone, str(mission.pk))
        return
    separation.reserve_way_down(failing.drone, then)
    transaction.on_commit(lambda: send_stop(failing_id, str(mission.pk)))
    transaction.on_commit(lambda: send_control(failing_id, "land"))


def _nothing_left(mission: Mission, failing: Assignment) -> None:
    record(
        mission,
        Event.Kind.DECISION,
        "nothing left to hand over",
        data={"decision": "no_replacement_needed", "assignment": str(failing.pk)},
    )


def _nearest_replacement(
    mission: Mission, failing: Assignment, target: tuple[float, float] | None
) -> Drone | None:
    """The available drone nearest to `target`, never one this mission already replaced."""
    replaced = mission.assignments.filter(replaced_by__isnull=False).values_list(
        "drone__drone_id", flat=True
    )
    found = nearest_available(
        mission.organisation_id, target=target, exclude=[failing.drone.drone_id, *replaced]
    )
    return found[0] if found else None


def _plan_handover(
    mission: Mission, view: list[dict], stop_position: tuple[float, float] | None, drone: Drone
) -> Handover | None:
    """The replacement's plan, or None (recorded) when no plan can reach the remaining steps."""
    try:
        handover = plan_replacement(
            view, stop_position=stop_position, altitude=mission.altitude, drone_id=drone.drone_id
        )
        handover = separation.layered_handover(handover, [drone])
        envelopes.check_steps(drone, handover.assignments[0].steps, fence=mission.fence)
    except PlanningError as exc:
        record(
            mission,
            Event.Kind.DECISION,
            f"replacement impossible: {exc}",
            data={"decision": "replacement_failed", "error": str(exc)},
        )
        return None
    except envelopes.OutsideEnvelope as exc:
        record(
            mission,
            Event.Kind.DECISION,
            f"replacement refused: {exc.message}",
            data={"decision": "replacement_failed", "code": exc.code},
        )
        return None
    return handover


def _commit(mission: Mission, failing: Assignment, drone: Drone, handover: Handover) -> Assignment:
    """Store the new steps and the replacing assignment; a paused mission runs again."""
    plan = handover.assignments[0]
    Step.objects.bulk_create(
        Step(mission=mission, index=s["index"], command=s["command"], params=s["params"])
        for s in handover.new_steps
    )
    replacement = Assignment.objects.create(
        mission=mission,
        drone=drone,
        step_indexes=plan.handed_over_indexes,
        preparation=plan.preparation_indexes,
        reason=Assignment.Reason.REPLACEMENT,
        status=Assignment.Status.SENT,
        replaces=failing,
    )
    if mission.status == MissionStatus.PAUSED:
        move_mission(mission, MissionStatus.RUNNING)
    return replacement


def _record_replacement(
    replacement: Assignment,
    plan: PlannedAssignment,
    stop_position: tuple[float, float] | None,
    alarm_event_id: int | None,
    timings: dict[str, float],
) -> None:
    """The decision (with its timings) and the handover it makes, for the mission log."""
    mission, drone, failing = replacement.mission, replacement.drone, replacement.replaces
    failing_id = failing.drone.drone_id
    record(
        mission,
        Event.Kind.DECISION,
        f"{drone.drone_id} replaces {failing_id}",
        drone=drone,
        data={
            "decision": "replacement",
            "failing": failing_id,
            "drone_id": drone.drone_id,
            "assignment": str(replacement.pk),
            "replaces": str(failing.pk),
            "alarm": alarm_event_id,
            **timings,
        },
    )
    record(
        mission,
        Event.Kind.HANDOVER,
        f"{failing_id} → {drone.drone_id}: {len(plan.handed_over_indexes)} steps",
        drone=drone,
        data={
            "from": failing_id,
            "to": drone.drone_id,
            "position": None
            if stop_position is None
            else {"lat": stop_position[0], "lon": stop_position[1]},
            "handed_over": plan.handed_over_indexes,
            "preparation": plan.preparation_indexes,
            "reason": "replacement",
        },
    )


def dispatch(assignment: Assignment) -> None:
    """Send the assignment, then note that it went (a re-run sends only what never went)."""
    send_assignment(assignment)
    Event.objects.create(
        mission_id=assignment.mission_id,
        drone=assignment.drone,
        kind=Event.Kind.DECISION,
        message=f"steps sent to {assignment.drone.drone_id}",
        data={"decision": "dispatched", "assignment": str(assignment.pk)},
    )


def _dispatched(assignment: Assignment) -> bool:
    return Event.objects.filter(
        mission_id=assignment.mission_id,
        data__decision="dispatched",
        data__assignment=str(assignment.pk),
    ).exists()


def _raising_step(mission: Mission, alarm: Event | None) -> set[int]:
    """A virtualalarm step did its work by raising the alarm: it is not handed over, even
    if its completion report arrives after the alarm (it does: the alarm comes first)."""
    index = alarm.data.get("index") if alarm is not None else None
    if (
        isinstance(index, int)
        and mission.steps.filter(index=index, command="virtualalarm").exists()
    ):
        return {index}
    return set()


def _first_navigation(steps: list[dict]) -> tuple[float, float] | None:
    for step in steps:
        if step["command"] == "navigate":
            return float(step["params"]["lat"]), float(step["params"]["lon"])
    return None


def _pause(
    mission: Mission,
    failing: Assignment,
    stop_position: tuple[float, float] | None,
    alarm: Event | None,
) -> None:
    if mission.status == MissionStatus.RUNNING:
        move_mission(mission, MissionStatus.PAUSED)
    already = mission.events.filter(
        kind=Event.Kind.DECISION, data__decision="paused", data__assignment=str(failing.pk)
    ).exists()
    if not already:
        record(
            mission,
            Event.Kind.DECISION,
            f"paused: no drone can replace {failing.drone.drone_id}; "
            "the mission resumes when one comes online",
            drone=failing.drone,
            data={
                "decision": "paused",
                "assignment": str(failing.pk),
                "alarm": None if alarm is None else alarm.pk,
                "operator_notice": True,
            },
        )


def resume_paused() -> list[str]:
    """Retry the replacement of every paused mission; the ids of those that resumed."""
    resumed = []
    for mission in Mission.objects.filter(status=MissionStatus.PAUSED):
        pause = (
            mission.events.filter(kind=Event.Kind.DECISION, data__decision="paused")
            .order_by("-at", "-id")
            .first()
        )
        if pause is None:
            continue
        replacement = replace_drone(
            mission_id=str(mission.pk),
            assignment_id=pause.data["assignment"],
            alarm_event_id=pause.data.get("alarm"),
        )
        if replacement is not None:
            resumed.append(str(mission.pk))
    return resumed

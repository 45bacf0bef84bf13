"""Collaborative extension on an OUT_MEASURE alarm, once per mission.

The area is rebuilt around the alarm position from the mission's extensibility parameters
(`vectors`, `step_distance`, `intermediate_action`), larger by 50 % per joining drone; the
new waypoints are split among the alarming drone and up to N nearest available drones.
The alarming drone is flying another assignment: it is told to stop first, and its new
part is queued until it reports the old one stopped (a drone runs one mission at a time).
A part is never sent to a drone on the ground without the steps to take off: an alarming
drone that has landed gets arm and takeoff in its part, and so does a queued part whose
drone landed before it was released (`ready_to_fly`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

from django.conf import settings
from django.db import transaction

from airspace import separation
from airspace.reservations import reserve_assignment
from fleet import envelopes
from fleet.models import Drone
from missions.handover import Assignment as PlannedPart
from missions.handover import Handover, plan_collaboration
from missions.journal import record
from missions.models import STEP_DONE, Assignment, Event, Mission, MissionStatus, Step, StepStatus
from missions.planning import (
    Extension,
    PlanningError,
    Vectors,
    extend_from_vectors,
    mission_steps,
)
from missions.selection import nearest_available
from missions.sending import send_assignment, send_stop
from onboard.protocol import DEFAULT_TOLERANCE


def _center(alarm: Event | None, alarming: Assignment) -> tuple[float, float] | None:
    position = alarm.data.get("position") if alarm is not None else None
    if isinstance(position, Mapping) and position.get("lat") is not None:
        return float(position["lat"]), float(position["lon"])
    drone = alarming.drone
    if drone.lat is not None and drone.lon is not None:
        return drone.lat, drone.lon
    return None


def _decline(mission: Mission, message: str, decision: str) -> list[Assignment]:
    record(mission, Event.Kind.DECISION, message, data={"decision": decision})
    return []


def collaborate(
    *, mission_id: str, assignment_id: str, alarm_event_id: int | None = None
) -> list[Assignment]:
    """Extend the mission around the alarm and dispatch one part per drone."""
    began = time.perf_counter()
    with transaction.atomic():
        mission = Mission.objects.select_for_update().filter(pk=mission_id).first()
        if mission is None or mission.status != MissionStatus.RUNNING:
            return []
        refusal = _why_not_extensible(mission)
        if refusal is not None:
            return _decline(mission, refusal, "collaboration_ignored")
        alarming = (
            Assignment.objects.select_related("drone")
            .filter(pk=assignment_id, mission=mission)
            .first()
        )
        if alarming is None:
            return []
        alarm = Event.objects.filter(pk=alarm_event_id, mission=mission).first()
        center = _center(alarm, alarming)
        if center is None:
            return _decline(mission, "the alarm has no position", "collaboration_ignored")
        joining = nearest_available(
            mission.organisation_id,
            target=center,
            count=settings.MISSIONS_JOINING_DRONES,
            exclude=[alarming.drone.drone_id],
        )
        plan_began = time.perf_counter()
        try:
            extension, handover = _plan(mission, center, alarming, joining)
        except PlanningError as exc:
            return _decline(mission, f"extension impossible: {exc}", "collaboration_failed")
        try:
            handover = separation.layered_handover(handover, [alarming.drone, *joining])
        except envelopes.OutsideEnvelope as exc:
            return _decline(mission, f"extension refused: {exc.message}", "collaboration_failed")
        refusal = _outside_envelope(handover, [alarming.drone, *joining], mission.fence)
        if refusal is not None:
            return _decline(mission, f"extension refused: {refusal}", "collaboration_failed")
        plan_ms = (time.perf_counter() - plan_began) * 1000
        _supersede(mission, handover)
        stopped = _stop_flying(mission)
        drones = [alarming.drone, *joining]
        created = _create_parts(mission, handover, drones, stopped)
        timings = {
            "plan_ms": round(plan_ms, 3),
            "task_ms": round((time.perf_counter() - began) * 1000, 3),
        }
        _record_collaboration(
            mission, alarming, center, drones, extension, handover, alarm_event_id, timings
        )
        _record_handovers(mission, alarming, center, created, handover)
    return created


def _outside_envelope(
    handover: Handover, drones: list[Drone], fence: dict | None = None
) -> str | None:
    """Why a part would take its drone out of its envelope (or the mission's own fence),
    or None: nothing is sent then."""
    by_id = {d.drone_id: d for d in drones}
    for part in handover.assignments:
        try:
            envelopes.check_steps(by_id[part.drone_id], part.steps, fence=fence)
        except envelopes.OutsideEnvelope as exc:
            return f"{part.drone_id}: {exc.message}"
    return None


def _why_not_extensible(mission: Mission) -> str | None:
    """The mission is extended once, and only with its extensibility parameters."""
    if mission.assignments.filter(reason=Assignment.Reason.COLLABORATION).exists():
        return "already extended: alarm noted"
    params = mission.extensibility or {}
    if not params.get("vectors") or not params.get("step_distance"):
        return "no extensibility parameters: alarm noted"
    return None


def _plan(
    mission: Mission,
    center: tuple[float, float],
    alarming: Assignment,
    joining: list[Drone],
) -> tuple[Extension, Handover]:
    """The rebuilt area around `center` and its split among the alarming and joining drones."""
    params = mission.extensibility
    extension = extend_from_vectors(
        Vectors.from_dict(params["vectors"]),
        params["step_distance"],
        center=center,
        joining_drones=len(joining),
        drone_positions=[list(center)] + [[d.lat, d.lon] for d in joining],
        max_waypoints=settings.MISSIONS_MAX_WAYPOINTS,
    )
    # Done steps count as completed for the planner, whatever way they ended.
    steps = [
        {
            "index": s.index,
            "command": s.command,
            "params": s.params,
            "status": StepStatus.COMPLETED if s.status in STEP_DONE else s.status,
        }
        for s in mission.steps.order_by("index")
    ]
    handover = plan_collaboration(
        steps,
        extension=extension,
        drone_ids=[d.drone_id for d in [alarming.drone, *joining]],
        alarming_drone=alarming.drone.drone_id,
        altitude=mission.altitude,
        intermediate_action=params.get("intermediate_action"),
        grounded=[alarming.drone.drone_id] if _landed(alarming) else [],
    )
    return extension, handover


def _landed(alarming: Assignment) -> bool:
    """The alarming drone has ended its steps and is on the ground: its part is sent at
    once, so it must take off. (A drone still flying its steps is told to stop and its
    part waits for its report; `ready_to_fly` looks again then.)"""
    return alarming.status not in Assignment.ACTIVE and not alarming.drone.airborne


def _supersede(mission: Mission, handover: Handover) -> None:
    """The old plan's steps not yet done are superseded; the new area's steps are stored."""
    mission.steps.filter(index__in=handover.superseded_indexes).exclude(
        status__in=STEP_DONE
    ).update(status=StepStatus.SUPERSEDED)
    Step.objects.bulk_create(
        Step(mission=mission, index=s["index"], command=s["command"], params=s["params"])
        for s in handover.new_steps
    )


def _stop_flying(mission: Mission) -> set[str]:
    """Every drone still flying the old plan stops (after the commit); their ids."""
    flying = list(mission.assignments.filter(status__in=Assignment.ACTIVE).select_related("drone"))
    mission.assignments.filter(status__in=Assignment.ACTIVE).update(
        status=Assignment.Status.STOPPED
    )
    for old in flying:
        drone_id = old.drone.drone_id
        transaction.on_commit(lambda d=drone_id: send_stop(d, str(mission.pk)))
    return {old.drone.drone_id for old in flying}


def _create_parts(
    mission: Mission, handover: Handover, drones: list[Drone], stopped: set[str]
) -> list[Assignment]:
    """One assignment per part: sent now, or queued for a drone that must stop first
    (a drone runs one mission at a time; its stop report releases the queued part)."""
    by_id = {d.drone_id: d for d in drones}
    created = []
    for part in handover.assignments:
        preparation = list(part.preparation_indexes)
        queued = part.drone_id in stopped
        assignment = Assignment.objects.create(
            mission=mission,
            drone=by_id[part.drone_id],
            step_indexes=[s["index"] for s in part.steps if s["index"] not in preparation],
            preparation=preparation,
            reason=Assignment.Reason.COLLABORATION,
            status=Assignment.Status.QUEUED if queued else Assignment.Status.SENT,
        )
        created.append(assignment)
        if not queued:
            transaction.on_commit(lambda a=assignment: send_assignment(a))
    return created


def _record_collaboration(
    mission: Mission,
    alarming: Assignment,
    center: tuple[float, float],
    drones: list[Drone],
    extension: Extension,
    handover: Handover,
    alarm_event_id: int | None,
    timings: dict[str, float],
) -> None:
    record(
        mission,
        Event.Kind.DECISION,
        f"extended around the alarm: {len(extension.waypoints)} waypoints over "
        f"{extension.area_m2:g} m² for {len(drones)} drones",
        drone=alarming.drone,
        data={
            "decision": "collaboration",
            "center": list(center),
            "waypoints": len(extension.waypoints),
            "area_m2": extension.area_m2,
            "target_area_m2": extension.target_area_m2,
            "shape": list(extension.shape),
            "drones": [d.drone_id for d in drones],
            "parts": [p.waypoint_indexes for p in extension.parts],
            "superseded": handover.superseded_indexes,
            "alarm": alarm_event_id,
            **timings,
        },
    )


def _record_handovers(
    mission: Mission,
    alarming: Assignment,
    center: tuple[float, float],
    created: list[Assignment],
    handover: Handover,
) -> None:
    for assignment, part in zip(created, handover.assignments, strict=True):
        record(
            mission,
            Event.Kind.HANDOVER,
            f"{part.drone_id}: {len(part.waypoint_indexes)} waypoints of the new area",
            drone=assignment.drone,
            data={
                "from": alarming.drone.drone_id,
                "to": part.drone_id,
                "position": {"lat": center[0], "lon": center[1]},
                "waypoints": part.waypoint_indexes,
                "preparation": part.preparation_indexes,
                "reason": "collaboration",
            },
        )


def ready_to_fly(assignment: Assignment) -> str | None:
    """Make a queued part flyable from where its drone is, just before it is sent; None
    when it is, else why not (nothing is changed then). A drone that landed before its
    part was released (its own plan ended on the ground) is given arm and takeoff to the
    mission's altitude first, laid on a layer or staggered as the split was
    (airspace/separation.py), within its envelope and the mission's fence."""
    drone = Drone.objects.get(pk=assignment.drone_id)
    mission = assignment.mission
    indexes = [*assignment.preparation, *assignment.step_indexes]
    by_index = {s.index: s for s in mission.steps.filter(index__in=indexes)}
    steps = [
        {"index": i, "command": by_index[i].command, "params": by_index[i].params}
        for i in indexes
        if i in by_index
    ]
    if drone.airborne or any(s["command"] == "takeoff" for s in steps):
        return None
    first = (mission.steps.order_by("-index").values_list("index", flat=True).first() or 0) + 1
    lift = mission_steps([], altitude=mission.altitude, append_land=False, start_index=first)
    # Climb, then go (as a joining drone: missions/handover.py plan_collaboration).
    tolerance = {"horizontal_tolerance": DEFAULT_TOLERANCE, "vertical_tolerance": DEFAULT_TOLERANCE}
    wait = next((s["params"] for s in steps if s["command"] == "wait_for_flight"), tolerance)
    lift.append({"index": first + 2, "command": "wait_for_flight", "params": dict(wait)})
    part = PlannedPart(drone.drone_id, "collaboration", [*lift, *steps], [s["index"] for s in lift])
    try:
        plan = separation.layered_handover(Handover([part], lift, []), [drone])
        envelopes.check_steps(drone, plan.assignments[0].steps, fence=mission.fence)
    except (envelopes.OutsideEnvelope, PlanningError) as exc:
        return f"{drone.drone_id} is on the ground and may not take off again: {exc.message}"
    Step.objects.bulk_create(
        Step(mission=mission, index=s["index"], command=s["command"], params=s["params"])
        for s in plan.new_steps
    )
    assignment.preparation = plan.assignments[0].preparation_indexes
    assignment.save(update_fields=["preparation"])
    reserve_assignment(assignment)
    record(
        mission,
        Event.Kind.DECISION,
        f"{drone.drone_id} landed before its part was sent: it takes off again first",
        drone=drone,
        data={"decision": "takes_off_again", "assignment": str(assignment.pk)},
    )
    return None

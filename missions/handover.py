"""Pure planning of handovers: which steps, with which indexes, go to which drone.

Replacement (on a CRITICAL alarm): the replacement drone gets preparation
steps (arm, take off to the mission altitude, fly to where the failing drone stopped)
and then every step not yet completed, with its ORIGINAL index, in index order.

Collaboration (on an OUT_MEASURE alarm): the rebuilt area's parts go to
the drones; the alarming drone, flying, keeps its part without preparation (one that
has landed arms and takes off again), each joining drone arms and takes off first. The
original mission's steps not yet completed are superseded by the new plan.

Index rule, for both: step indexes are the mission's index space (docs/protocol.md: an index
is kept when a step changes hands, and it must be ≥ 0), so every NEW step — preparation
or a new area's waypoint — gets a fresh index after the mission's highest one, in the
order listed here. New steps are therefore mission steps like any other: the caller
stores them (`new_steps`) before dispatching, and no index is ever reused or skipped.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from missions.planning import Extension, PlanningError, mission_steps
from onboard.protocol import DEFAULT_TOLERANCE

COMPLETED = "completed"
PREPARATION = "preparation"
REPLACEMENT = "replacement"
COLLABORATION = "collaboration"


@dataclass(frozen=True)
class Assignment:
    """The steps one drone is sent, in flying order."""

    drone_id: str | None
    reason: str  # "replacement" or "collaboration"
    steps: list[dict]
    preparation_indexes: list[int]  # new steps that only bring the drone into position
    handed_over_indexes: list[int] = field(default_factory=list)  # existing steps it takes on
    waypoint_indexes: list[int] = field(default_factory=list)  # its part of a new area

    def to_dict(self) -> dict:
        return {
            "drone_id": self.drone_id,
            "reason": self.reason,
            "steps": self.steps,
            "preparation_indexes": self.preparation_indexes,
            "handed_over_indexes": self.handed_over_indexes,
            "waypoint_indexes": self.waypoint_indexes,
        }


@dataclass(frozen=True)
class Handover:
    assignments: list[Assignment]
    new_steps: list[dict]  # steps to add to the mission, index order
    superseded_indexes: list[int]  # existing steps no drone will fly any more

    def to_dict(self) -> dict:
        return {
            "assignments": [a.to_dict() for a in self.assignments],
            "new_steps": self.new_steps,
            "superseded_indexes": self.superseded_indexes,
        }


def _indexed(steps: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The mission's steps in index order, refusing missing or repeated indexes."""
    seen: set[int] = set()
    for i, step in enumerate(steps):
        index = step.get("index")
        if isinstance(index, bool) or not isinstance(index, int) or index < 0:
            raise PlanningError(f"steps[{i}].index", "must be a whole number ≥ 0")
        if index in seen:
            raise PlanningError(f"steps[{i}].index", f"index {index} appears twice")
        if not isinstance(step.get("command"), str):
            raise PlanningError(f"steps[{i}].command", "is required")
        seen.add(index)
    return sorted(steps, key=lambda s: s["index"])


def _plain(step: Mapping[str, Any]) -> dict:
    return {
        "index": step["index"],
        "command": step["command"],
        "params": dict(step.get("params") or {}),
    }


def _renumber(body: list[tuple[str, dict]], start: int) -> list[dict]:
    return [
        {"index": start + i, "command": command, "params": params}
        for i, (command, params) in enumerate(body)
    ]


def _last_navigation_target(done: list[Mapping[str, Any]]) -> tuple[float, float] | None:
    for step in reversed(done):
        if step["command"] == "navigate":
            params = step.get("params") or {}
            return float(params["lat"]), float(params["lon"])
    return None


def _preparation(
    done: list[Mapping[str, Any]],
    remaining: list[Mapping[str, Any]],
    stop_position: tuple[float, float] | None,
    altitude: float,
    wait: dict[str, float],
) -> list[tuple[str, dict]]:
    """Arm, take off and fly to where the failing drone stopped; then back to its last
    waypoint when the first remaining step must happen there (a wait or an action)."""
    # mission_steps validates the altitude and the coordinates for us.
    target = (
        (float(stop_position[0]), float(stop_position[1]))
        if stop_position is not None
        else _last_navigation_target(done)
    )
    points = [] if target is None else [target]
    body = [
        (s["command"], s["params"])
        for s in mission_steps(
            points,
            altitude=altitude,
            append_land=False,
            wait_tolerance=(wait["horizontal_tolerance"], wait["vertical_tolerance"]),
        )
    ]
    # Climb, then go: a takeoff does not wait for its height, so without a wait the drone
    # would cross other drones' layers on a slant on its way out (reserved as flown, the
    # slant's low pieces would meet the layers under it: airspace/corridors.py).
    body.insert(2, ("wait_for_flight", dict(wait)))
    waypoint = _last_navigation_target(done)
    first = remaining[0]["command"]
    needs_waypoint = first not in ("navigate", "land", "takeoff", "arm")
    if waypoint is not None and needs_waypoint and waypoint != target:
        body.append(("navigate", {"lat": waypoint[0], "lon": waypoint[1]}))
        if first != "wait_for_flight":
            body.append(("wait_for_flight", dict(wait)))
    return body


def plan_replacement(
    steps: Sequence[Mapping[str, Any]],
    *,
    stop_position: tuple[float, float] | None,
    altitude: float,
    drone_id: str | None = None,
    wait_tolerance: tuple[float, float] = (DEFAULT_TOLERANCE, DEFAULT_TOLERANCE),
) -> Handover:
    """The replacement drone's steps: preparation, then every step not completed.

    `steps` are the mission's steps as mappings with index, command, params and status
    (only "completed" counts as done). Preparation (arm, takeoff to `altitude`, navigate
    to `stop_position` and wait_for_flight) is left out when nothing was completed yet
    and the mission still starts with its own arm. If the first remaining step is not a
    navigation (the failing drone had reached a waypoint but not finished there), the
    drone is also sent to that waypoint, so its wait or action happens at the right place.
    With no `stop_position` (no GPS fix), the last completed waypoint stands in for it.
    """
    ordered = _indexed(steps)
    done = [s for s in ordered if s.get("status") == COMPLETED]
    remaining = [s for s in ordered if s.get("status") != COMPLETED]
    if not remaining:
        raise PlanningError("steps", "every step is completed: nothing to hand over")
    next_index = ordered[-1]["index"] + 1
    horizontal, vertical = wait_tolerance
    wait = {"horizontal_tolerance": float(horizontal), "vertical_tolerance": float(vertical)}

    starts_from_scratch = not done and remaining[0]["command"] == "arm"
    body = (
        [] if starts_from_scratch else _preparation(done, remaining, stop_position, altitude, wait)
    )
    preparation = _renumber(body, next_index)
    handed = [_plain(s) for s in remaining]
    assignment = Assignment(
        drone_id=drone_id,
        reason=REPLACEMENT,
        steps=preparation + handed,
        preparation_indexes=[s["index"] for s in preparation],
        handed_over_indexes=[s["index"] for s in handed],
    )
    return Handover(assignments=[assignment], new_steps=preparation, superseded_indexes=[])


def plan_collaboration(
    steps: Sequence[Mapping[str, Any]],
    *,
    extension: Extension,
    drone_ids: Sequence[str],
    alarming_drone: str,
    altitude: float,
    intermediate_action: Any = None,
    wait_tolerance: tuple[float, float] = (DEFAULT_TOLERANCE, DEFAULT_TOLERANCE),
    grounded: Sequence[str] = (),
) -> Handover:
    """One assignment per part of `extension` (made with drone positions, see `split`).

    `drone_ids[i]` is the drone whose position was `drone_positions[i]`. The alarming
    drone's assignment is its part and a final land; each joining drone's starts with
    arm, takeoff to `altitude` and a wait for that height, and so does the alarming drone's when it is among the
    `grounded` (it landed before the split: it must take off again). New indexes follow the mission's highest, part by part
    in path order. The original mission's steps not yet completed are superseded.
    """
    ordered = _indexed(steps)
    if alarming_drone not in drone_ids:
        raise PlanningError("alarming_drone", f"{alarming_drone!r} is not among the drones")
    if len(set(drone_ids)) != len(drone_ids):
        raise PlanningError("drone_ids", "a drone appears twice")
    if any(part.drone is None for part in extension.parts):
        raise PlanningError("extension", "its parts have no drones: split it with drone positions")
    if len(extension.parts) != len(drone_ids):
        raise PlanningError("drone_ids", f"expected {len(extension.parts)} drones, one per part")
    next_index = (ordered[-1]["index"] + 1) if ordered else 0
    assignments: list[Assignment] = []
    new_steps: list[dict] = []
    for part in extension.parts:
        drone_id = drone_ids[part.drone]  # type: ignore[index]
        takes_off = drone_id != alarming_drone or drone_id in grounded
        waypoints = [extension.waypoints[i] for i in part.waypoint_indexes]
        built = _part_steps(
            waypoints, altitude, intermediate_action, wait_tolerance, takes_off, next_index
        )
        next_index += len(built)
        assignments.append(
            Assignment(
                drone_id=drone_id,
                reason=COLLABORATION,
                steps=built,
                preparation_indexes=[s["index"] for s in built[:3]] if takes_off else [],
                waypoint_indexes=list(part.waypoint_indexes),
            )
        )
        new_steps += built
    superseded = [s["index"] for s in ordered if s.get("status") != COMPLETED]
    return Handover(assignments=assignments, new_steps=new_steps, superseded_indexes=superseded)


def _part_steps(
    waypoints: list[Any],
    altitude: float,
    intermediate_action: Any,
    wait_tolerance: tuple[float, float],
    takes_off: bool,
    start_index: int,
) -> list[dict]:
    """A split part's steps from `start_index`: [arm, takeoff, wait for its height,] the
    waypoints, land."""
    built = mission_steps(
        waypoints,
        altitude=altitude,
        intermediate_action=intermediate_action,
        prepend_takeoff=takes_off,
        append_land=True,
        wait_tolerance=wait_tolerance,
        start_index=start_index,
    )
    if not takes_off:
        return built
    # mission_steps puts arm and takeoff first. Climb, then go: a takeoff does not wait
    # for its height, and a drone laid on a layer would otherwise cross the lower layers
    # on a slant on its way out (its layer is reserved above its column, then along its
    # legs: airspace/corridors.py).
    horizontal, vertical = (float(t) for t in wait_tolerance)
    climb = {
        "command": "wait_for_flight",
        "params": {"horizontal_tolerance": horizontal, "vertical_tolerance": vertical},
    }
    built = [*built[:2], climb, *built[2:]]
    return [{**step, "index": start_index + i} for i, step in enumerate(built)]

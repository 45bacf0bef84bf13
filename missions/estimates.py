"""How far each drone of a mission is, how long it still needs and the battery it will have
left: plain functions over the mission's steps, and the one read of them from the database.

The estimate: the distance still to fly (from where the drone is, through its remaining
waypoints) over its measured speed, and its measured battery drain over that time.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from .geo import distance_m
from .models import STEP_DONE, Assignment, Step, StepStatus

# Speed assumed before a drone has flown a measurable leg of the mission (m/s).
DEFAULT_SPEED_M_S = 5.0
# Legs shorter or quicker than this say nothing reliable about speed.
MIN_LEG_M = 5.0
MIN_LEG_S = 1.0


def estimate(
    remaining_m: float,
    speed_m_s: float | None,
    battery_remaining: float | None,
    drain_per_s: float | None,
    reserve: float = 0.0,
) -> dict:
    """Time still needed (s) and the battery left at the end, and its margin over
    `reserve` (fractions 0..1); each None when its input is not known."""
    speed = speed_m_s if speed_m_s and speed_m_s > 0 else DEFAULT_SPEED_M_S
    seconds = max(0.0, remaining_m) / speed
    at_end = None
    if battery_remaining is not None and drain_per_s is not None and drain_per_s >= 0:
        at_end = battery_remaining - drain_per_s * seconds
    return {
        "time_remaining_s": round(seconds, 1),
        "battery_at_end": None if at_end is None else round(at_end, 4),
        "battery_margin": None if at_end is None else round(at_end - reserve, 4),
    }


def route_length(start: Sequence[float] | None, waypoints: Sequence[Sequence[float]]) -> float:
    """Metres from `start` ([lat, lon], or the first waypoint) through `waypoints` in order."""
    points = ([list(start)] if start is not None else []) + [list(p) for p in waypoints]
    if len(points) < 2:
        return 0.0
    lats, lons = zip(*points, strict=True)
    return float(distance_m(lats[:-1], lons[:-1], lats[1:], lons[1:]).sum())


def measured_speed(legs: Iterable[tuple[Sequence[float], float]]) -> float | None:
    """Mean ground speed over consecutive (position [lat, lon], time s) points of completed
    waypoints; None when no leg is long enough to tell."""
    metres = seconds = 0.0
    previous = None
    for point, t in legs:
        if previous is not None:
            d = route_length(previous[0], [point])
            dt = t - previous[1]
            if d >= MIN_LEG_M and dt >= MIN_LEG_S:
                metres, seconds = metres + d, seconds + dt
        previous = (point, t)
    return metres / seconds if seconds else None


@dataclass
class DroneRoute:
    """One drone's share of a mission, as the page shows it."""

    drone_id: str
    assignment_status: str
    total: int
    done: int
    current: int | None
    planned: list[list[float]] = field(default_factory=list)  # waypoints still to fly
    speed_m_s: float | None = None

    def progress(
        self,
        position: dict | None,
        battery_remaining: float | None,
        drain_per_s: float | None,
        reserve: float,
    ) -> dict:
        start = None if position is None else [position["lat"], position["lon"]]
        remaining = route_length(start, self.planned)
        return {
            "drone_id": self.drone_id,
            "assignment_status": self.assignment_status,
            "steps_done": self.done,
            "steps_total": self.total,
            "current_step": self.current,
            "remaining_m": round(remaining, 1),
            "speed_m_s": None if self.speed_m_s is None else round(self.speed_m_s, 2),
            "battery": battery_remaining,
            **estimate(remaining, self.speed_m_s, battery_remaining, drain_per_s, reserve),
        }


def _waypoint(step: Step) -> list[float] | None:
    params = step.params or {}
    if step.command != "navigate" or "lat" not in params or "lon" not in params:
        return None
    return [float(params["lat"]), float(params["lon"])]


def route_of(assignment: Assignment, steps: dict[int, Step]) -> DroneRoute:
    """The drone's assigned steps: how many are done, the first not done, the waypoints
    left and the speed measured on the waypoints it reached."""
    mine = [steps[i] for i in assignment.step_indexes if i in steps]
    done = [s for s in mine if s.status in STEP_DONE]
    left = [s for s in mine if s.status not in STEP_DONE]
    reached = sorted(
        (s for s in done if s.status == StepStatus.COMPLETED and s.position and s.ended_at),
        key=lambda s: s.ended_at,
    )
    legs = [([s.position["lat"], s.position["lon"]], s.ended_at.timestamp()) for s in reached]
    return DroneRoute(
        drone_id=assignment.drone.drone_id,
        assignment_status=assignment.status,
        total=len(mine),
        done=len(done),
        current=left[0].index if left else None,
        planned=[p for p in map(_waypoint, left) if p is not None],
        speed_m_s=measured_speed(legs),
    )


def mission_routes(mission_id: object) -> dict[str, DroneRoute]:
    """Per drone, its latest assignment of the mission (a replaced drone keeps its own)."""
    steps = {s.index: s for s in Step.objects.filter(mission_id=mission_id)}
    routes: dict[str, DroneRoute] = {}
    assignments = Assignment.objects.filter(mission_id=mission_id).select_related("drone")
    for assignment in assignments.order_by("created_at"):
        routes[assignment.drone.drone_id] = route_of(assignment, steps)
    return routes

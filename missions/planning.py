"""Coverage geometry for missions: plain values in, plain values out.

The user clicks three consecutive corners A, B, C of a parallelogram. In a local metric
frame (missions.geo), v = B − A and w = C − B; the fourth corner is A + w. A side of
length L holds floor(L / step) + 1 waypoints, so consecutive waypoints are exactly one
step apart, and the path is a serpentine: rows run along v, the first from A towards B,
each next row one step further along w and in the opposite direction.

`vectors` and `step_distance` (with `intermediate_action`) are the mission's extensibility
parameters: enough to rebuild the same shape around a new centre (`extend_from_vectors`).
"""

from __future__ import annotations

import gc
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from missions.geo import MAX_ABS_LATITUDE, LocalFrame, distance_m
from onboard.protocol import DEFAULT_TOLERANCE, MAX_ALTITUDE, ProtocolError, validate_command

DEFAULT_MAX_WAYPOINTS = 50_000
# A parallelogram flatter than this (sin of the angle between v and w) is a line.
MIN_SIN_ANGLE = 0.01
# Metres lost to the lat/lon round trip must not drop a waypoint: 32 m at 8 m is 5, not 4.
_LENGTH_EPSILON = 1e-6
# Steps one may put after every waypoint: they act where the drone is and move nothing.
INTERMEDIATE_COMMANDS = ("takepic", "sense", "sleep", "objrequest")
# Trying every assignment of parts to drones costs k!; beyond this, greedy.
EXHAUSTIVE_SPLIT_MAX = 6


class PlanningError(ValueError):
    """Bad planning input; `field` names the request field (the API answers 400 with both)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message

    def to_dict(self) -> dict:
        return {"field": self.field, "error": self.message}


@dataclass(frozen=True)
class Vectors:
    """v and w in metres, each (north, east)."""

    v: tuple[float, float]
    w: tuple[float, float]

    def to_dict(self) -> dict:
        return {"v": list(self.v), "w": list(self.w)}

    @classmethod
    def from_dict(cls, data: Any) -> Vectors:
        """The stored extensibility parameter back; PlanningError if it is not {"v", "w"}."""
        if not isinstance(data, Mapping):
            raise PlanningError("vectors", "must be an object with v and w")
        pairs = []
        for name in ("v", "w"):
            value = data.get(name)
            if not (isinstance(value, Sequence) and not isinstance(value, str) and len(value) == 2):
                raise PlanningError(f"vectors.{name}", "must be [north, east] in metres")
            pairs.append(
                (_finite(value[0], f"vectors.{name}"), _finite(value[1], f"vectors.{name}"))
            )
        return cls(v=pairs[0], w=pairs[1])


@dataclass(frozen=True)
class Coverage:
    waypoints: list[list[float]]  # [[lat, lon], ...] in flying order
    area_m2: float
    vectors: Vectors
    step_distance: float
    shape: tuple[int, int]  # (rows along w, waypoints per row along v)

    def to_dict(self) -> dict:
        return {
            "waypoints": self.waypoints,
            "area_m2": self.area_m2,
            "vectors": self.vectors.to_dict(),
            "step_distance": self.step_distance,
            "shape": list(self.shape),
        }


@dataclass(frozen=True)
class Part:
    """A contiguous run of waypoint indexes and the drone (index into the positions) flying it."""

    waypoint_indexes: list[int]
    drone: int | None = None
    travel_m: float | None = None  # from the drone to the part's first waypoint

    def to_dict(self) -> dict:
        return {
            "waypoint_indexes": self.waypoint_indexes,
            "drone": self.drone,
            "travel_m": self.travel_m,
        }


@dataclass(frozen=True)
class Extension:
    waypoints: list[list[float]]
    area_m2: float
    target_area_m2: float
    vectors: Vectors  # the new area's sides, same directions as the original's
    step_distance: float
    shape: tuple[int, int]
    center: tuple[float, float]
    parts: list[Part]

    def to_dict(self) -> dict:
        return {
            "waypoints": self.waypoints,
            "area_m2": self.area_m2,
            "target_area_m2": self.target_area_m2,
            "vectors": self.vectors.to_dict(),
            "step_distance": self.step_distance,
            "shape": list(self.shape),
            "center": list(self.center),
            "parts": [part.waypoint_indexes for part in self.parts],
            "drones": [part.drone for part in self.parts],
        }


# ---------------------------------------------------------------------------------------
# Validation helpers.


def _finite(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise PlanningError(field, f"must be a number, got {value!r}")
    result = float(value)
    if not math.isfinite(result):
        raise PlanningError(field, "must be a finite number")
    return result


def _latlon(value: Any, field: str) -> tuple[float, float]:
    if not (isinstance(value, Sequence) and not isinstance(value, str) and len(value) == 2):
        raise PlanningError(field, "must be [lat, lon]")
    lat = _finite(value[0], field)
    lon = _finite(value[1], field)
    if not -MAX_ABS_LATITUDE <= lat <= MAX_ABS_LATITUDE:
        raise PlanningError(field, f"latitude {lat:g} is outside ±{MAX_ABS_LATITUDE:g}°")
    if not -180.0 <= lon <= 180.0:
        raise PlanningError(field, f"longitude {lon:g} is outside ±180°")
    return lat, lon


def parse_point(value: Any, field: str) -> tuple[float, float]:
    """[lat, lon] checked for range; PlanningError naming `field` otherwise."""
    return _latlon(value, field)


def _step(step_distance: Any, field: str = "step_distance") -> float:
    step = _finite(step_distance, field)
    if step <= 0:
        raise PlanningError(field, f"must be greater than 0, got {step:g}")
    return step


def _check_count(count: int, max_waypoints: int) -> None:
    if count > max_waypoints:
        raise PlanningError(
            "step_distance",
            f"the area needs {count} waypoints, more than the limit of {max_waypoints}; "
            "use a larger step or a smaller area",
        )


def _shape_of(v: NDArray, w: NDArray, field: str = "vertices") -> tuple[float, float, float]:
    """|v|, |w| and sin of the angle between them, refusing degenerate areas."""
    len_v = float(np.hypot(*v))
    len_w = float(np.hypot(*w))
    if len_v == 0.0 or len_w == 0.0:
        raise PlanningError(field, "two consecutive vertices coincide")
    sin_angle = abs(float(v[0] * w[1] - v[1] * w[0])) / (len_v * len_w)
    if sin_angle < MIN_SIN_ANGLE:
        raise PlanningError(field, "the three vertices are collinear: they enclose no area")
    return len_v, len_w, sin_angle


# ---------------------------------------------------------------------------------------
# Grids.


def _serpentine_ne(
    origin: NDArray,
    v_hat: NDArray,
    w_hat: NDArray,
    n_v: int,
    n_w: int,
    step: float,
    row_step: float | None = None,
) -> tuple[NDArray, NDArray]:
    """North/east of an n_w × n_v grid, rows along v `step` apart point to point and
    `row_step` (default `step`) apart row to row, alternate rows reversed."""
    rows = np.repeat(np.arange(n_w), n_v)
    cols = np.tile(np.arange(n_v), n_w)
    cols = np.where(rows % 2 == 1, n_v - 1 - cols, cols)
    along_v = cols * step
    along_w = rows * (step if row_step is None else row_step)
    north = origin[0] + along_v * v_hat[0] + along_w * w_hat[0]
    east = origin[1] + along_v * v_hat[1] + along_w * w_hat[1]
    return north, east


def _points(frame: LocalFrame, north: NDArray, east: NDArray) -> list[list[float]]:
    lat, lon = frame.to_latlon(north, east)
    rows = np.column_stack((lat, lon))
    # tolist() makes one list per waypoint; the cyclic GC would rescan every live object
    # several times while tens of thousands are made (3-4x the cost). Lists of floats
    # cannot form cycles, so pausing it here loses nothing.
    enabled = gc.isenabled()
    gc.disable()
    try:
        return rows.tolist()
    finally:
        if enabled:
            gc.enable()


def _waypoints_per_side(length: float, step: float) -> int:
    return math.floor(length / step + _LENGTH_EPSILON) + 1


def coverage(
    vertices: Sequence[Sequence[float]],
    step_distance: float,
    *,
    max_waypoints: int = DEFAULT_MAX_WAYPOINTS,
    line_spacing: float | None = None,
) -> Coverage:
    """Serpentine waypoints covering the parallelogram of three consecutive vertices: lines
    along A→B with waypoints `step_distance` apart, lines `line_spacing` (default the same)
    apart towards C."""
    if not (isinstance(vertices, Sequence) and len(vertices) == 3):
        raise PlanningError("vertices", "must be exactly three [lat, lon] points")
    points = [_latlon(vertex, f"vertices[{i}]") for i, vertex in enumerate(vertices)]
    step = _step(step_distance)
    row_step = step if line_spacing is None else _step(line_spacing, "line_spacing")
    frame = LocalFrame(*points[0])
    north, east = frame.to_ne([p[0] for p in points], [p[1] for p in points])
    a, b, c = np.column_stack((north, east))
    v, w = b - a, c - b
    len_v, len_w, sin_angle = _shape_of(v, w)
    n_v = _waypoints_per_side(len_v, step)
    n_w = _waypoints_per_side(len_w, row_step)
    _check_count(n_v * n_w, max_waypoints)
    grid_n, grid_e = _serpentine_ne(a, v / len_v, w / len_w, n_v, n_w, step, row_step)
    return Coverage(
        waypoints=_points(frame, grid_n, grid_e),
        area_m2=round(len_v * len_w * sin_angle, 3),
        vectors=Vectors(v=(float(v[0]), float(v[1])), w=(float(w[0]), float(w[1]))),
        step_distance=step,
        shape=(n_w, n_v),
    )


# ---------------------------------------------------------------------------------------
# Extension.


def _extended_steps(steps_v: float, steps_w: float, target_steps2: float) -> tuple[int, int]:
    """Whole steps per side for the grid closest in area to the target (see `extend`).

    Candidates are the grids reached by scaling both sides by one factor s and rounding
    each side to whole steps (halves up), so the shape keeps its aspect; the candidate
    changes only where steps·s crosses a half step, so one s between each pair of
    consecutive crossings visits every candidate.
    """
    s_max = 2.0 * math.sqrt(target_steps2 / (steps_v * steps_w)) + 1.0
    crossings = [np.array([0.0, s_max])]
    for steps in (steps_v, steps_w):
        halves = (np.arange(math.ceil(s_max * steps + 0.5)) + 0.5) / steps
        crossings.append(halves[halves < s_max])
    ordered = np.unique(np.concatenate(crossings))
    s = (ordered[:-1] + ordered[1:]) / 2.0
    m = np.maximum(1, np.floor(steps_v * s + 0.5)).astype(np.int64)
    n = np.maximum(1, np.floor(steps_w * s + 0.5)).astype(np.int64)
    # Closest area first; on a tie the smaller grid (fewer waypoints to fly).
    best = np.lexsort((n, m, m * n, np.abs(m * n - target_steps2)))[0]
    return int(m[best]), int(n[best])


def extend_from_vectors(
    vectors: Vectors | Mapping,
    step_distance: float,
    *,
    center: Sequence[float],
    joining_drones: int,
    drone_positions: Sequence[Sequence[float]] | None = None,
    max_waypoints: int = DEFAULT_MAX_WAYPOINTS,
) -> Extension:
    """Rebuild the stored shape around `center`, larger by 50 % per joining drone.

    Rule ([Paula 2018], §5.4.4): the target area is the original |v × w| × (1 + 0.5 × joining
    drones); the step and the directions of v and w are kept. Both sides are scaled by
    one factor and rounded to whole steps (the aspect is kept); of those grids, the one
    whose area is closest to the target wins, a tie going to the smaller. The experiment's
    28 × 35 m at 7 m (4 × 5 steps, 980 m²) with two joining drones targets 1960 m²: the
    candidates around it are 5 × 7 steps (1715 m², +75 %) and 6 × 7 steps (2058 m²,
    +110 %), so 6 × 7 steps = 42 × 49 m, 7 × 8 = 56 waypoints, as there.

    The waypoints are split into joining_drones + 1 contiguous parts; with
    `drone_positions` (one [lat, lon] per drone, the alarming drone first by convention)
    each part is also given the drone that reaches its first waypoint best (`split`).
    """
    if not isinstance(vectors, Vectors):
        vectors = Vectors.from_dict(vectors)
    step = _step(step_distance)
    center_ll = _latlon(center, "center")
    _check_joining(joining_drones)
    v = np.asarray(vectors.v, dtype=float)
    w = np.asarray(vectors.w, dtype=float)
    len_v, len_w, sin_angle = _shape_of(v, w, "vectors")
    original_area = len_v * len_w * sin_angle
    target_area = original_area * (1.0 + 0.5 * joining_drones)
    target_steps2 = target_area / (step * step * sin_angle)
    # The chosen grid has about target_steps2 cells, so refuse huge ones before the search.
    _check_count(math.ceil(target_steps2 / 2), max_waypoints)
    m, n = _extended_steps(len_v / step, len_w / step, target_steps2)
    _check_count((m + 1) * (n + 1), max_waypoints)
    v_hat, w_hat = v / len_v, w / len_w
    new_v, new_w = v_hat * m * step, w_hat * n * step
    frame = LocalFrame(*center_ll)
    origin = -(new_v + new_w) / 2.0
    grid_n, grid_e = _serpentine_ne(origin, v_hat, w_hat, m + 1, n + 1, step)
    waypoints = _points(frame, grid_n, grid_e)
    return Extension(
        waypoints=waypoints,
        area_m2=round(m * n * step * step * sin_angle, 3),
        target_area_m2=target_area,
        vectors=Vectors(v=(float(new_v[0]), float(new_v[1])), w=(float(new_w[0]), float(new_w[1]))),
        step_distance=step,
        shape=(n + 1, m + 1),
        center=center_ll,
        parts=_parts(waypoints, joining_drones + 1, drone_positions),
    )


def _check_joining(joining_drones: int) -> None:
    if isinstance(joining_drones, bool) or not isinstance(joining_drones, int):
        raise PlanningError("joining_drones", "must be a whole number")
    if joining_drones < 0:
        raise PlanningError("joining_drones", "must not be negative")


def _parts(
    waypoints: list[list[float]], count: int, drone_positions: Sequence[Sequence[float]] | None
) -> list[Part]:
    """`count` contiguous parts; with drone positions, each given the drone it suits best."""
    if drone_positions is None:
        return [Part(indexes) for indexes in _chunks(len(waypoints), count)]
    if len(drone_positions) != count:
        raise PlanningError("drone_positions", f"expected {count} positions (joining drones + 1)")
    return split(waypoints, drone_positions)


def extend(
    vertices: Sequence[Sequence[float]],
    step_distance: float,
    *,
    center: Sequence[float],
    joining_drones: int,
    drone_positions: Sequence[Sequence[float]] | None = None,
    max_waypoints: int = DEFAULT_MAX_WAYPOINTS,
) -> Extension:
    """`extend_from_vectors` for an area given by its three vertices (the API's form)."""
    original = coverage(vertices, step_distance, max_waypoints=max_waypoints)
    return extend_from_vectors(
        original.vectors,
        step_distance,
        center=center,
        joining_drones=joining_drones,
        drone_positions=drone_positions,
        max_waypoints=max_waypoints,
    )


# ---------------------------------------------------------------------------------------
# Split.


def _chunks(total: int, count: int) -> list[list[int]]:
    """0..total-1 in `count` contiguous runs whose sizes differ by at most one."""
    size, extra = divmod(total, count)
    runs, start = [], 0
    for i in range(count):
        end = start + size + (1 if i < extra else 0)
        runs.append(list(range(start, end)))
        start = end
    return runs


def _assign(cost: NDArray) -> list[int]:
    """drone for each part, minimising total travel (then the longest leg)."""
    k = cost.shape[0]
    if k <= EXHAUSTIVE_SPLIT_MAX:
        parts = np.arange(k)
        best_key, best = None, None
        for perm in itertools.permutations(range(k)):
            legs = cost[list(perm), parts]
            key = (float(legs.sum()), float(legs.max()))
            if best_key is None or key < best_key:
                best_key, best = key, list(perm)
        assert best is not None
        return best
    # Greedy: repeatedly take the shortest remaining (drone, part) leg.
    drone_for_part = [-1] * k
    free_drones, free_parts = set(range(k)), set(range(k))
    order = np.dstack(np.unravel_index(np.argsort(cost, axis=None), cost.shape))[0]
    for drone, part in order:
        if drone in free_drones and part in free_parts:
            drone_for_part[int(part)] = int(drone)
            free_drones.discard(drone)
            free_parts.discard(part)
    return drone_for_part


def split(
    waypoints: Sequence[Sequence[float]], drone_positions: Sequence[Sequence[float]]
) -> list[Part]:
    """Split waypoints into one contiguous, near-equal part per drone and pair them up.

    Parts keep the serpentine order and come back in path order; `drone` is the index in
    `drone_positions` of the drone flying it, chosen so the drones' travel to their first
    waypoints is small (every assignment tried for up to six drones, greedy beyond).
    """
    k = len(drone_positions)
    if k == 0:
        raise PlanningError("drone_positions", "at least one drone is needed")
    if len(waypoints) < k:
        raise PlanningError("drone_positions", f"{k} drones for {len(waypoints)} waypoints")
    drones = np.array([_latlon(p, f"drone_positions[{i}]") for i, p in enumerate(drone_positions)])
    runs = _chunks(len(waypoints), k)
    firsts = np.array(
        [_latlon(waypoints[run[0]], f"waypoints[{run[0]}]") for run in runs], dtype=float
    )
    cost = distance_m(
        drones[:, None, 0], drones[:, None, 1], firsts[None, :, 0], firsts[None, :, 1]
    )
    drone_for_part = _assign(cost)
    return [
        Part(run, drone=drone, travel_m=float(cost[drone, part]))
        for part, (run, drone) in enumerate(zip(runs, drone_for_part, strict=True))
    ]


# ---------------------------------------------------------------------------------------
# Steps.


def normalise_actions(intermediate_action: Any) -> list[dict]:
    """None, "takepic", {"command", "params"} or a list of those → validated step bodies."""
    if intermediate_action is None:
        return []
    raw = intermediate_action if isinstance(intermediate_action, list) else [intermediate_action]
    actions = []
    for i, item in enumerate(raw):
        field = "intermediate_action" if len(raw) == 1 else f"intermediate_action[{i}]"
        command: Any
        params: Any
        if isinstance(item, str):
            command, params = item, {}
        elif isinstance(item, Mapping):
            command, params = item.get("command"), item.get("params") or {}
        else:
            raise PlanningError(field, "must be a command name or {command, params}")
        if command not in INTERMEDIATE_COMMANDS:
            raise PlanningError(
                field,
                f"{command!r} cannot follow every waypoint; use one of "
                + ", ".join(INTERMEDIATE_COMMANDS),
            )
        try:
            params = validate_command(command, params, mission=True)
        except ProtocolError as exc:
            raise PlanningError(f"{field}.{exc.field}", exc.message) from None
        actions.append({"command": command, "params": params})
    return actions


def mission_steps(
    waypoints: Sequence[Sequence[float]],
    *,
    altitude: float,
    intermediate_action: Any = None,
    prepend_takeoff: bool = True,
    append_land: bool = True,
    wait_tolerance: tuple[float, float] = (DEFAULT_TOLERANCE, DEFAULT_TOLERANCE),
    start_index: int = 0,
) -> list[dict]:
    """Mission steps flying the waypoints: [arm, takeoff,] (navigate, wait, actions…)*, [land].

    Indexes run from `start_index` in list order. `wait_tolerance` is (horizontal, vertical)
    in metres for every wait_for_flight.
    """
    alt = _finite(altitude, "altitude")
    if not 0.5 <= alt <= MAX_ALTITUDE:
        raise PlanningError("altitude", f"must be between 0.5 and {MAX_ALTITUDE:g} m")
    horizontal, vertical = (_finite(t, "wait_tolerance") for t in wait_tolerance)
    if horizontal <= 0 or vertical <= 0:
        raise PlanningError("wait_tolerance", "must be greater than 0")
    actions = normalise_actions(intermediate_action)
    points = [_latlon(p, f"waypoints[{i}]") for i, p in enumerate(waypoints)]
    body: list[tuple[str, dict]] = []
    if prepend_takeoff:
        body += [("arm", {}), ("takeoff", {"altitude": alt})]
    wait = {"horizontal_tolerance": horizontal, "vertical_tolerance": vertical}
    for lat, lon in points:
        body.append(("navigate", {"lat": lat, "lon": lon}))
        body.append(("wait_for_flight", dict(wait)))
        body += [(a["command"], dict(a["params"])) for a in actions]
    if append_land:
        body.append(("land", {}))
    return [
        {"index": start_index + i, "command": command, "params": params}
        for i, (command, params) in enumerate(body)
    ]


def followed_steps(
    points: Sequence[tuple[float, float, float, bool, float]],
    *,
    altitude: float,
    intermediate_action: Any = None,
) -> list[dict]:
    """Mission steps flying (lat, lon, height above home, is a waypoint, speed m/s)
    points, each leg climbing or descending to its point's height at its speed: arm, take
    off to `altitude` and wait to reach it, then navigate and wait at every point, with the
    intermediate actions at waypoints only (points added between waypoints to follow the
    terrain take no photo); land."""
    alt = _finite(altitude, "altitude")
    if not 0.5 <= alt <= MAX_ALTITUDE:
        raise PlanningError("altitude", f"must be between 0.5 and {MAX_ALTITUDE:g} m")
    actions = normalise_actions(intermediate_action)
    wait = {"horizontal_tolerance": DEFAULT_TOLERANCE, "vertical_tolerance": DEFAULT_TOLERANCE}
    # The take-off's height is reached over home before the first leg: a takeoff does not
    # wait for its height, and a leg begun on the way up would meet rising ground below
    # the height it is to follow.
    body: list[tuple[str, dict]] = [("arm", {}), ("takeoff", {"altitude": alt})]
    body.append(("wait_for_flight", dict(wait)))
    height = alt
    for lat, lon, target, waypoint, speed in points:
        delta = round(target - height, 3)
        leg = {"lat": lat, "lon": lon, "altitude_delta": delta, "speed": round(speed, 2)}
        body.append(("navigate", leg))
        body.append(("wait_for_flight", dict(wait)))
        if waypoint:
            body += [(a["command"], dict(a["params"])) for a in actions]
        height += delta
    body.append(("land", {}))
    return [{"index": i, "command": c, "params": p} for i, (c, p) in enumerate(body)]

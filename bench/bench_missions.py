"""Mission planning speed: numpy coverage and extension + split against plain-Python loops.

Run: .venv/bin/python -m bench.bench_missions

Both sides compute the same thing in the same run (the loop versions are checked to give
the same waypoints): a 1 km² square at 5 m (201 × 201 = 40 401 waypoints), and that area
extended around a new centre for two joining drones (+100 %) and split among three.
"""

from __future__ import annotations

import itertools
import math

from bench.common import best_of, record
from missions.geo import EARTH_RADIUS_M, LocalFrame
from missions.planning import coverage, extend_from_vectors

FRAME = LocalFrame(40.6303, -8.6575)
SIDE_M = 1000.0
STEP_M = 5.0
MAX_WAYPOINTS = 200_000


def square_vertices() -> list[list[float]]:
    lat, lon = FRAME.to_latlon([0.0, 0.0, SIDE_M], [0.0, SIDE_M, SIDE_M])
    return [[float(a), float(b)] for a, b in zip(lat, lon, strict=True)]


# ---------------------------------------------------------------------------------------
# The baseline: the same planning written as straightforward loops over math.


def _loop_to_ne(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    north = EARTH_RADIUS_M * math.radians(lat - lat0)
    east = EARTH_RADIUS_M * math.cos(math.radians(lat0)) * math.radians(lon - lon0)
    return north, east


def _loop_to_latlon(lat0: float, lon0: float, north: float, east: float) -> list[float]:
    lat = lat0 + math.degrees(north / EARTH_RADIUS_M)
    lon = lon0 + math.degrees(east / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    return [lat, lon]


def _loop_grid(lat0, lon0, origin, v_hat, w_hat, n_v, n_w, step) -> list[list[float]]:
    points = []
    for row in range(n_w):
        columns = range(n_v) if row % 2 == 0 else range(n_v - 1, -1, -1)
        for col in columns:
            north = origin[0] + col * step * v_hat[0] + row * step * w_hat[0]
            east = origin[1] + col * step * v_hat[1] + row * step * w_hat[1]
            points.append(_loop_to_latlon(lat0, lon0, north, east))
    return points


def loop_coverage(vertices: list[list[float]], step: float) -> list[list[float]]:
    lat0, lon0 = vertices[0]
    a, b, c = (_loop_to_ne(lat0, lon0, lat, lon) for lat, lon in vertices)
    v = (b[0] - a[0], b[1] - a[1])
    w = (c[0] - b[0], c[1] - b[1])
    len_v, len_w = math.hypot(*v), math.hypot(*w)
    n_v = math.floor(len_v / step + 1e-6) + 1
    n_w = math.floor(len_w / step + 1e-6) + 1
    v_hat = (v[0] / len_v, v[1] / len_v)
    w_hat = (w[0] / len_w, w[1] / len_w)
    return _loop_grid(lat0, lon0, a, v_hat, w_hat, n_v, n_w, step)


def _haversine(lat1, lon1, lat2, lon2) -> float:
    p1, p2 = math.radians(lat1), math.radians(lat2)
    a = (
        math.sin((p2 - p1) / 2) ** 2
        + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    )
    return 2 * EARTH_RADIUS_M * math.asin(math.sqrt(min(1.0, a)))


def loop_extend_split(vectors, step, center, joining, drones) -> tuple[list, list[int]]:
    v, w = vectors
    len_v, len_w = math.hypot(*v), math.hypot(*w)
    a0, b0 = len_v / step, len_w / step
    target = a0 * b0 * (1 + 0.5 * joining)
    best = None
    s = 0.0005
    while s < 2 * math.sqrt(target / (a0 * b0)) + 1:
        m = max(1, math.floor(a0 * s + 0.5))
        n = max(1, math.floor(b0 * s + 0.5))
        key = (abs(m * n - target), m * n, m, n)
        best = key if best is None or key < best else best
        s += 0.0005
    _, _, m, n = best
    v_hat = (v[0] / len_v, v[1] / len_v)
    w_hat = (w[0] / len_w, w[1] / len_w)
    origin = (
        -(v_hat[0] * m * step + w_hat[0] * n * step) / 2,
        -(v_hat[1] * m * step + w_hat[1] * n * step) / 2,
    )
    points = _loop_grid(center[0], center[1], origin, v_hat, w_hat, m + 1, n + 1, step)
    k = len(drones)
    size, extra = divmod(len(points), k)
    parts, start = [], 0
    for i in range(k):
        end = start + size + (1 if i < extra else 0)
        parts.append(list(range(start, end)))
        start = end
    starts = [part[0] for part in parts]
    best_perm, best_cost = None, None
    for perm in itertools.permutations(range(k)):
        legs = [_haversine(*drones[d], *points[starts[p]]) for p, d in enumerate(perm)]
        cost = (sum(legs), max(legs))
        if best_cost is None or cost < best_cost:
            best_perm, best_cost = list(perm), cost
    return points, best_perm


# ---------------------------------------------------------------------------------------


def _max_difference(ours: list[list[float]], theirs: list[list[float]]) -> float:
    assert len(ours) == len(theirs), (len(ours), len(theirs))
    return max(
        abs(a - b) for p, q in zip(ours, theirs, strict=True) for a, b in zip(p, q, strict=True)
    )


def bench_coverage() -> None:
    vertices = square_vertices()
    ours = coverage(vertices, STEP_M, max_waypoints=MAX_WAYPOINTS).waypoints
    assert _max_difference(ours, loop_coverage(vertices, STEP_M)) < 1e-9
    numpy_s = best_of(lambda: coverage(vertices, STEP_M, max_waypoints=MAX_WAYPOINTS), repeat=5)
    loop_s = best_of(lambda: loop_coverage(vertices, STEP_M), repeat=3)
    record(
        "missions.coverage_1km2_5m",
        value=numpy_s,
        unit="s",
        baseline_name="pure-Python loops",
        baseline_value=loop_s,
        higher_is_better=False,
        goal="well under the loop time; 40 401 waypoints in a blink for the planner page",
        waypoints=len(ours),
    )


def bench_extend_split() -> None:
    base = coverage(square_vertices(), STEP_M, max_waypoints=MAX_WAYPOINTS)
    center = FRAME.point_to_latlon([300.0, 400.0])
    drones = [center, FRAME.point_to_latlon([-400.0, 0.0]), FRAME.point_to_latlon([900, 900])]
    vectors = (base.vectors.v, base.vectors.w)

    def ours():
        return extend_from_vectors(
            base.vectors,
            STEP_M,
            center=center,
            joining_drones=2,
            drone_positions=drones,
            max_waypoints=MAX_WAYPOINTS,
        )

    result = ours()
    loop_points, loop_perm = loop_extend_split(vectors, STEP_M, center, 2, drones)
    assert _max_difference(result.waypoints, loop_points) < 1e-9
    assert [part.drone for part in result.parts] == loop_perm
    numpy_s = best_of(ours, repeat=5)
    loop_s = best_of(lambda: loop_extend_split(vectors, STEP_M, center, 2, drones), repeat=3)
    record(
        "missions.extend_split",
        value=numpy_s,
        unit="s",
        baseline_name="pure-Python loops",
        baseline_value=loop_s,
        higher_is_better=False,
        goal="well under the loop time; a collaboration is planned within the alarm's handling",
        waypoints=len(result.waypoints),
    )


def main() -> None:
    bench_coverage()
    bench_extend_split()


if __name__ == "__main__":
    main()

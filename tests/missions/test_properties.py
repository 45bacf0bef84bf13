"""Properties that hold for any area, any split and any point of failure."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from missions.geo import distance_m
from missions.handover import plan_replacement
from missions.planning import coverage, extend_from_vectors, mission_steps, split
from tests.missions.planning import AVEIRO, point_at

metres = st.floats(min_value=-300, max_value=300, allow_nan=False)
steps = st.floats(min_value=4, max_value=40, allow_nan=False)


def _area(a, b, c):
    return abs((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]))


@settings(max_examples=60, deadline=None)
@given(st.tuples(metres, metres), st.tuples(metres, metres), st.tuples(metres, metres), steps)
def test_any_parallelogram_gets_floor_plus_one_waypoints_per_side_one_step_apart(a, b, c, step):
    v = np.subtract(b, a)
    w = np.subtract(c, b)
    len_v, len_w = np.hypot(*v), np.hypot(*w)
    # Away from the degenerate cases (refused) and from exact multiples of the step.
    if min(len_v, len_w) < 1 or _area(a, b, c) / (len_v * len_w) < 0.05:
        return
    if any(abs(x / step - round(x / step)) < 0.05 for x in (len_v, len_w)):
        return
    result = coverage([list(point_at(*p)) for p in (a, b, c)], step)
    expected = (math.floor(len_v / step) + 1) * (math.floor(len_w / step) + 1)
    assert len(result.waypoints) == expected
    # The planner's frame sits on vertex A, the test's on the campus: both linearise the
    # sphere, so they agree to a few parts per million over these distances.
    assert math.isclose(result.area_m2, _area(a, b, c), rel_tol=1e-4)
    if expected > 1:
        points = np.array(result.waypoints)
        gaps = distance_m(points[:-1, 0], points[:-1, 1], points[1:, 0], points[1:, 1])
        # Exact in the planning frame; on the sphere the east scale drifts with latitude
        # by ~1e-5 per 100 m from the reference, far below GPS noise.
        assert np.allclose(gaps, step, rtol=1e-4)


@settings(max_examples=40, deadline=None)
@given(
    st.tuples(metres, metres).filter(lambda v: np.hypot(*v) > 10),
    st.floats(min_value=0.3, max_value=2.8),
    st.integers(min_value=0, max_value=4),
)
def test_an_extension_keeps_the_step_and_is_the_closest_aspect_kept_grid(v, turn, joining):
    length = np.hypot(*v)
    w = (
        length * 0.7 * math.cos(math.atan2(v[1], v[0]) + turn),
        length * 0.7 * math.sin(math.atan2(v[1], v[0]) + turn),
    )
    result = extend_from_vectors(
        {"v": list(v), "w": list(w)}, 5, center=point_at(0, 0), joining_drones=joining
    )
    points = np.array(result.waypoints)
    gaps = distance_m(points[:-1, 0], points[:-1, 1], points[1:, 0], points[1:, 1])
    assert np.allclose(gaps, 5, rtol=1e-4)
    target = _area((0, 0), v, np.add(v, w)) * (1 + 0.5 * joining)
    assert math.isclose(result.target_area_m2, target, rel_tol=1e-9)
    # No bigger-or-equal neighbour of the same aspect would have come closer.
    rows, cols = result.shape
    sin_angle = result.area_m2 / ((rows - 1) * (cols - 1) * 25)
    for dm, dn in ((1, 1), (-1, -1)):
        m, n = cols - 1 + dm, rows - 1 + dn
        if m >= 1 and n >= 1:
            assert abs(result.area_m2 - target) <= abs(m * n * 25 * sin_angle - target) + 1e-6
    north, east = AVEIRO.to_ne(points[:, 0], points[:, 1])
    assert abs(north.mean()) < 1e-3 and abs(east.mean()) < 1e-3


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=1, max_value=400),
    st.lists(st.tuples(metres, metres), min_size=1, max_size=8),
)
def test_any_split_is_contiguous_near_equal_and_gives_each_drone_one_part(count, drones):
    if len(drones) > count:
        return
    waypoints = [list(point_at(i * 1.0, 0)) for i in range(count)]
    parts = split(waypoints, [point_at(*d) for d in drones])
    assert [i for p in parts for i in p.waypoint_indexes] == list(range(count))
    sizes = [len(p.waypoint_indexes) for p in parts]
    assert max(sizes) - min(sizes) <= 1
    assert sorted(p.drone for p in parts) == list(range(len(drones)))


@settings(max_examples=60, deadline=None)
@given(st.integers(min_value=-1, max_value=57), st.booleans())
def test_a_replacement_at_any_step_does_every_index_exactly_once(completed_through, has_fix):
    waypoints = coverage([list(point_at(0, 0)), list(point_at(0, 32)), list(point_at(64, 32))], 10)
    steps = mission_steps(waypoints.waypoints, altitude=10, intermediate_action="takepic")
    tracked = [
        {**s, "status": "completed" if s["index"] <= completed_through else "pending"}
        for s in steps
    ]
    stop = point_at(3, 4) if has_fix else None
    plan = plan_replacement(tracked, stop_position=stop, altitude=10)
    (assignment,) = plan.assignments
    first = [s["index"] for s in tracked if s["status"] == "completed"]
    done = Counter(first + assignment.handed_over_indexes)
    assert sorted(done) == [s["index"] for s in steps]
    assert set(done.values()) == {1}
    sent = [s["index"] for s in assignment.steps]
    assert len(sent) == len(set(sent))
    assert set(assignment.preparation_indexes).isdisjoint(s["index"] for s in steps)
    assert [s["index"] for s in assignment.steps if s["index"] < len(steps)] == sorted(
        assignment.handed_over_indexes
    )

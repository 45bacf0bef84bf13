from __future__ import annotations

import math

import numpy as np
import pytest

from missions.geo import EARTH_RADIUS_M, LocalFrame, distance_m
from missions.planning import (
    PlanningError,
    Vectors,
    coverage,
    extend,
    extend_from_vectors,
    mission_steps,
    split,
)
from tests.missions.planning import AVEIRO, metres_between, point_at, rectangle


def test_local_frame_round_trips_points_to_the_millimetre():
    north = np.linspace(-800, 800, 41)
    east = np.linspace(900, -900, 41)
    lat, lon = AVEIRO.to_latlon(north, east)
    back_n, back_e = AVEIRO.to_ne(lat, lon)
    assert np.max(np.abs(back_n - north)) < 1e-6
    assert np.max(np.abs(back_e - east)) < 1e-6


def test_local_frame_follows_the_dronin_linearisation():
    north, east = AVEIRO.to_ne(40.6303 + 0.001, -8.6575 + 0.001)
    assert float(north) == pytest.approx(EARTH_RADIUS_M * math.radians(0.001))
    assert float(east) == pytest.approx(
        EARTH_RADIUS_M * math.cos(math.radians(40.6303)) * math.radians(0.001)
    )


def test_local_frame_keeps_an_area_across_the_antimeridian_compact():
    frame = LocalFrame(10.0, 179.9999)
    _, east = frame.to_ne(10.0, -179.9999)
    assert float(east) == pytest.approx(21.9, abs=0.1)


def test_aerial_photography_area_gives_45_waypoints_over_2048_m2():
    result = coverage(rectangle(32, 64), 8)
    assert len(result.waypoints) == 45
    assert result.shape == (9, 5)
    assert result.area_m2 == pytest.approx(2048, abs=0.01)
    assert result.vectors.v == pytest.approx((0.0, 32.0), abs=1e-6)
    assert result.vectors.w == pytest.approx((64.0, 0.0), abs=1e-6)


def test_self_replacement_area_at_ten_metres_gives_28_waypoints():
    assert len(coverage(rectangle(32, 64), 10).waypoints) == 28


def test_collaborative_sensing_area_gives_30_waypoints_over_980_m2():
    result = coverage(rectangle(35, 28), 7)
    assert len(result.waypoints) == 30
    assert result.area_m2 == pytest.approx(980, abs=0.01)


def test_consecutive_waypoints_are_one_step_apart_along_a_serpentine():
    vertices = [list(point_at(0, 0)), list(point_at(30, 40)), list(point_at(90, 10))]
    result = coverage(vertices, 6)
    points = np.array(result.waypoints)
    gaps = distance_m(points[:-1, 0], points[:-1, 1], points[1:, 0], points[1:, 1])
    assert np.allclose(gaps, 6.0, atol=1e-3)
    assert result.waypoints[0] == pytest.approx(vertices[0])
    # The first row runs from A towards B, the second comes back.
    rows, per_row = result.shape
    assert per_row == math.floor(50 / 6) + 1
    assert metres_between(result.waypoints[per_row - 1], vertices[1]) < 6
    assert metres_between(result.waypoints[per_row], result.waypoints[per_row - 1]) == (
        pytest.approx(6.0, abs=1e-3)
    )


def test_every_waypoint_lies_inside_the_parallelogram():
    vertices = [list(point_at(0, 0)), list(point_at(10, 50)), list(point_at(70, 45))]
    result = coverage(vertices, 5)
    north, east = AVEIRO.to_ne(*np.array(result.waypoints).T)
    v = np.array([10.0, 50.0])
    w = np.array([60.0, -5.0])
    coords = np.linalg.solve(np.column_stack((v, w)), np.vstack((north, east)))
    assert coords.min() > -1e-9 and coords.max() < 1 + 1e-9


@pytest.mark.parametrize(
    ("vertices", "step", "field"),
    [
        (rectangle(32, 64)[:2], 8, "vertices"),
        ([[40.0, -8.0], [40.0001, -8.0001], [40.0002, -8.0002]], 2, "vertices"),
        ([[40.0, -8.0], [40.0, -8.0], [40.001, -8.0]], 2, "vertices"),
        (rectangle(32, 64), 0, "step_distance"),
        (rectangle(32, 64), -3, "step_distance"),
        (rectangle(32, 64), float("nan"), "step_distance"),
        ([[91.0, 0.0], [40.0, 0.0], [40.0, 1.0]], 8, "vertices[0]"),
        ([[40.0, 0.0], [40.0, 181.0], [40.0, 1.0]], 8, "vertices[1]"),
        ([[40.0, 0.0], [40.0, 1.0], "north"], 8, "vertices[2]"),
    ],
)
def test_bad_areas_are_refused_naming_the_field(vertices, step, field):
    with pytest.raises(PlanningError) as caught:
        coverage(vertices, step)
    assert caught.value.field == field


def test_too_many_waypoints_are_refused_before_any_is_built():
    with pytest.raises(PlanningError, match="limit of 1000"):
        coverage(rectangle(1000, 1000), 1, max_waypoints=1000)


def test_one_square_kilometre_at_five_metres_is_about_forty_thousand_waypoints():
    assert len(coverage(rectangle(1000, 1000), 5).waypoints) == 201 * 201


def test_extension_reproduces_56_waypoints_over_2058_m2():
    centre = point_at(14, 17.5)
    result = extend(rectangle(35, 28), 7, center=centre, joining_drones=2)
    assert len(result.waypoints) == 56
    assert result.area_m2 == pytest.approx(2058)
    assert result.target_area_m2 == pytest.approx(1960)
    lengths = sorted([np.hypot(*result.vectors.v), np.hypot(*result.vectors.w)])
    assert lengths == pytest.approx([42, 49])
    assert len(result.parts) == 3


def test_extension_keeps_the_step_and_the_direction_and_centres_the_area():
    centre = point_at(100, -40)
    vectors = Vectors(v=(20.0, 20.0), w=(-30.0, 30.0))
    result = extend_from_vectors(vectors, 5, center=centre, joining_drones=1)
    points = np.array(result.waypoints)
    gaps = distance_m(points[:-1, 0], points[:-1, 1], points[1:, 0], points[1:, 1])
    assert np.allclose(gaps, 5.0, atol=1e-3)
    v = np.array(result.vectors.v)
    assert v / np.hypot(*v) == pytest.approx(np.array([1, 1]) / math.sqrt(2))
    north, east = AVEIRO.to_ne(points[:, 0], points[:, 1])
    assert (north.mean(), east.mean()) == pytest.approx((100, -40), abs=1e-3)


def test_extension_area_is_the_closest_of_the_grids_around_the_target():
    # 4 × 5 steps at 7 m, two joining drones: 5 × 7 steps is 75 % larger, 6 × 7 is 110 %.
    result = extend(rectangle(35, 28), 7, center=point_at(0, 0), joining_drones=2)
    assert abs(result.area_m2 - 1960) < abs(35 * 49 - 1960)
    assert extend(rectangle(35, 28), 7, center=point_at(0, 0), joining_drones=0).area_m2 == 980


def test_extension_refuses_a_negative_number_of_drones():
    with pytest.raises(PlanningError) as caught:
        extend(rectangle(35, 28), 7, center=point_at(0, 0), joining_drones=-1)
    assert caught.value.field == "joining_drones"


def test_extension_refuses_stored_vectors_of_the_wrong_shape():
    with pytest.raises(PlanningError) as caught:
        extend_from_vectors({"v": [1, 2, 3], "w": [0, 1]}, 5, center=(40, -8), joining_drones=1)
    assert caught.value.field == "vectors.v"


def test_split_gives_contiguous_near_equal_parts_covering_every_waypoint():
    waypoints = coverage(rectangle(60, 50), 5).waypoints
    drones = [point_at(0, 0), point_at(50, 60), point_at(25, 30), point_at(-10, 0)]
    parts = split(waypoints, drones)
    sizes = [len(p.waypoint_indexes) for p in parts]
    assert max(sizes) - min(sizes) <= 1
    assert [i for p in parts for i in p.waypoint_indexes] == list(range(len(waypoints)))
    assert sorted(p.drone for p in parts) == [0, 1, 2, 3]


def test_split_sends_each_drone_to_the_part_that_starts_nearest():
    waypoints = coverage(rectangle(60, 60), 5).waypoints  # 13 rows of 13
    firsts = [waypoints[0], waypoints[57], waypoints[113]]
    # Drones placed just beside the parts' starts, listed in a shuffled order.
    drones = [firsts[2], firsts[0], firsts[1]]
    parts = split(waypoints, drones)
    assert [p.drone for p in parts] == [1, 2, 0]
    assert all(p.travel_m == pytest.approx(0, abs=1e-6) for p in parts)


def test_split_with_many_drones_still_covers_everything_greedily():
    waypoints = coverage(rectangle(100, 100), 5).waypoints
    drones = [point_at(i * 7.0, 100 - i * 9.0) for i in range(9)]
    parts = split(waypoints, drones)
    assert sorted(p.drone for p in parts) == list(range(9))
    assert sum(len(p.waypoint_indexes) for p in parts) == len(waypoints)


def test_split_refuses_more_drones_than_waypoints():
    with pytest.raises(PlanningError):
        split([[40.0, -8.0]], [(40.0, -8.0), (40.0, -8.0)])


def test_mission_steps_fly_every_waypoint_with_its_action_then_land():
    waypoints = coverage(rectangle(32, 64), 8).waypoints
    steps = mission_steps(waypoints, altitude=10, intermediate_action="takepic")
    assert [s["index"] for s in steps] == list(range(len(steps)))
    assert [s["command"] for s in steps[:2]] == ["arm", "takeoff"]
    assert steps[1]["params"] == {"altitude": 10.0}
    assert steps[-1]["command"] == "land"
    body = steps[2:-1]
    assert len(body) == 45 * 3
    assert [s["command"] for s in body[:3]] == ["navigate", "wait_for_flight", "takepic"]
    assert body[0]["params"] == {"lat": waypoints[0][0], "lon": waypoints[0][1]}
    assert body[1]["params"] == {"horizontal_tolerance": 2.0, "vertical_tolerance": 2.0}


def test_mission_steps_accept_sense_and_sleep_actions_with_their_parameters():
    steps = mission_steps(
        [[40.0, -8.0]],
        altitude=10,
        intermediate_action=[
            {"command": "sense", "params": {"sensor": "CO2"}},
            {"command": "sleep", "params": {"value": 2}},
        ],
        prepend_takeoff=False,
        append_land=False,
        start_index=7,
    )
    assert [(s["index"], s["command"]) for s in steps] == [
        (7, "navigate"),
        (8, "wait_for_flight"),
        (9, "sense"),
        (10, "sleep"),
    ]
    assert steps[2]["params"] == {"sensor": "CO2"}
    assert steps[3]["params"] == {"value": 2.0}


@pytest.mark.parametrize(
    ("action", "field"),
    [
        ("navigate", "intermediate_action"),
        ({"command": "sense"}, "intermediate_action.params.sensor"),
        ({"command": "sleep", "params": {"value": -1}}, "intermediate_action.params.value"),
        (42, "intermediate_action"),
    ],
)
def test_mission_steps_refuse_bad_intermediate_actions(action, field):
    with pytest.raises(PlanningError) as caught:
        mission_steps([[40.0, -8.0]], altitude=10, intermediate_action=action)
    assert caught.value.field == field


def test_mission_steps_refuse_an_altitude_out_of_range():
    with pytest.raises(PlanningError) as caught:
        mission_steps([[40.0, -8.0]], altitude=0)
    assert caught.value.field == "altitude"


def test_an_extension_too_large_for_the_cap_is_refused_before_it_is_built():
    with pytest.raises(PlanningError, match="limit of 50000"):
        extend(rectangle(35, 28), 7, center=point_at(0, 0), joining_drones=10**9)
    with pytest.raises(PlanningError, match="limit of 50000"):
        extend_from_vectors(
            {"v": [0, 1000], "w": [1000, 0]}, 0.001, center=(40, -8), joining_drones=1
        )

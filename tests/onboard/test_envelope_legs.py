"""The straight legs between targets against the geofence (onboard/envelope.py), without a drone.

Rule: the leg a drone flies from its current target to the next must not cross an
exclusion zone nor leave the inclusion zones, even when both of its ends are allowed.
"""

from __future__ import annotations

import pytest

from onboard import envelope as env

HOME = (40.6300, -8.6600)


def _square(half_m: float, north: float = 0.0, east: float = 0.0) -> list[list[float]]:
    """A square of side 2·half_m metres centred `north`, `east` metres from home."""
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return [list(env.ned_to_latlon(north + n, east + e, HOME)) for n, e in corners]


def _envelope(polygons=(), circles=()) -> env.Envelope:  # type: ignore[no-untyped-def]
    fence = {"version": 2, "polygons": list(polygons), "circles": list(circles)}
    return env.parse_envelope({"geoFence": fence}, home=HOME)


def _circle(north: float, east: float, radius: float, inclusion: bool = False) -> dict:
    center = list(env.ned_to_latlon(north, east, HOME))
    return {"inclusion": inclusion, "circle": {"center": center, "radius": radius}, "version": 1}


def _goto(north: float, east: float, height: float = 10.0) -> env.Move:
    return env.Move("goto", (north, east, -height), True)


EXCLUSION_SQUARE = {"inclusion": False, "polygon": _square(20, north=100), "version": 1}


@pytest.mark.parametrize(
    ("zone", "words"),
    [
        ({"polygons": [EXCLUSION_SQUARE]}, "exclusion polygon 0"),
        ({"circles": [_circle(100, 0, 20)]}, "exclusion circle 0"),
    ],
)
def test_a_leg_through_an_exclusion_zone_is_refused_though_both_ends_are_outside_it(
    zone: dict, words: str
) -> None:
    envelope = _envelope(**zone)
    start, end = (0.0, 0.0, -10.0), _goto(200, 0)
    assert env.check(envelope, HOME, end, True, 90.0) is None  # the end alone is allowed
    violation = env.check(envelope, HOME, end, True, 90.0, start)
    assert violation is not None and violation.limit == "geofence"
    assert words in violation.message and "leg" in violation.message
    (from_lat, _), (to_lat, _) = violation.leg
    assert from_lat == pytest.approx(HOME[0]) and to_lat > from_lat


@pytest.mark.parametrize(
    "zone", [{"polygons": [EXCLUSION_SQUARE]}, {"circles": [_circle(100, 0, 20)]}]
)
def test_a_leg_beside_an_exclusion_zone_is_accepted(zone: dict) -> None:
    # 30 m east of the zone's centre line: clear of a 20 m half-width or radius.
    assert env.check(_envelope(**zone), HOME, _goto(200, 30), True, 90.0, (0, 30, -10)) is None


def test_a_leg_cutting_the_corner_of_a_concave_inclusion_zone_is_refused() -> None:
    # An L: the square of 100 m about home with its north-east corner (beyond 20 m) cut out.
    corners = [(-100, -100), (-100, 100), (20, 100), (20, 20), (100, 20), (100, -100)]
    polygon = [list(env.ned_to_latlon(n, e, HOME)) for n, e in corners]
    envelope = _envelope(polygons=[{"inclusion": True, "polygon": polygon, "version": 1}])
    start, end = (10.0, 80.0, -10.0), _goto(80, 10)
    assert env.check(envelope, HOME, end, True, 90.0) is None
    violation = env.check(envelope, HOME, end, True, 90.0, start)
    assert violation is not None and "leaves the geofence's inclusion zones" in violation.message
    # Round the corner instead: each leg stays inside.
    assert env.check(envelope, HOME, _goto(10, 10), True, 90.0, start) is None
    assert env.check(envelope, HOME, end, True, 90.0, (10.0, 10.0, -10.0)) is None


def test_a_leg_across_two_overlapping_inclusion_zones_is_inside_their_union() -> None:
    envelope = _envelope(circles=[_circle(0, 0, 60, True), _circle(100, 0, 60, True)])
    assert env.check(envelope, HOME, _goto(150, 0), True, 90.0, (0.0, 0.0, -10.0)) is None
    # Between two zones that do not meet, the leg leaves both.
    apart = _envelope(circles=[_circle(0, 0, 40, True), _circle(150, 0, 40, True)])
    violation = env.check(apart, HOME, _goto(150, 0), True, 90.0, (0.0, 0.0, -10.0))
    assert violation is not None and "inclusion" in violation.message


def test_a_drone_inside_an_exclusion_zone_may_fly_out_of_it() -> None:
    envelope = _envelope(circles=[_circle(100, 0, 20)])
    assert env.check(envelope, HOME, _goto(200, 0), True, 90.0, (100.0, 0.0, -10.0)) is None


def test_climbing_in_place_is_no_leg() -> None:
    envelope = _envelope(circles=[_circle(0, 30, 20)])
    move = env.Move("goto", (0.0, 0.0, -40.0), False)
    assert env.check(envelope, HOME, move, True, 90.0, (0.0, 0.0, -10.0)) is None


def test_a_mission_walk_names_the_step_whose_leg_crosses() -> None:
    envelope = _envelope(circles=[_circle(100, 0, 20)])
    north = env.ned_to_latlon(200, 0, HOME)
    east = env.ned_to_latlon(200, 60, HOME)
    steps = [
        {"command": "takeoff", "params": {"altitude": 10}},
        {"command": "changeE", "params": {"value": 60}},
        {"command": "navigate", "params": {"lat": east[0], "lon": east[1]}},
        # Arrived before turning north: else the drone may cut the corner through the zone.
        {
            "command": "wait_for_flight",
            "params": {"horizontal_tolerance": 2, "vertical_tolerance": 2},
        },
        {"command": "navigate", "params": {"lat": north[0], "lon": north[1]}},
        {"command": "navigate", "params": {"lat": HOME[0], "lon": HOME[1]}},
    ]
    found = env.step_violations(envelope, HOME, steps, (0.0, 0.0, 0.0), False, None)
    # Up the east side is clear; back home from 200 m north crosses the zone.
    assert [(v.index, v.violation.limit) for v in found] == [(5, "geofence")]
    assert "exclusion circle 0" in found[0].violation.message


def test_the_guard_refuses_the_leg_from_the_given_start(tmp_path) -> None:  # type: ignore[no-untyped-def]
    guard = env.EnvelopeGuard(tmp_path / "envelope.json")
    guard.update({"geoFence": {"circles": [_circle(100, 0, 20)]}})

    class State:
        home = (*HOME, 12.0)
        airborne = True
        battery_remaining = 0.9

    start = (0.0, 0.0, -10.0)
    refusal = guard.refusal("changeN", "goto", (200.0, 0.0, -10.0), State(), False, start)
    assert refusal is not None and "exclusion circle 0" in refusal
    assert guard.refusal("changeN", "goto", (200.0, 0.0, -10.0), State(), False) is None

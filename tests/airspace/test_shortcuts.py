"""Legs sent before the last one ends are reserved as a fan (airspace/corridors.py): a
`navigate` sent while the one before it is still under way (no `wait_for_flight` between
them) may be flown from anywhere along that one, so besides its planned leg it reserves
legs from points at most 10 m apart along it to its target. A conflict met only by the
shortcut refuses the start; with a wait the drone flies through the corner and the same
flight is accepted."""

from __future__ import annotations

import pytest

from airspace.corridors import Pace, flight_legs, ground_distance, offset
from airspace.index import Airspace, Flight, Reserved
from airspace.models import Reservation
from missions.models import Assignment
from onboard.envelope import FAN_SPACING_M
from tests.missions.conftest import point_at

from .test_separation import crossing, start, two_drones  # noqa: F401

ORIGIN = (40.6303, -8.6575)
T = 1_800_000_000.0
PACE = Pace(speed_m_s=5.0, climb_m_s=2.0, slack=0.5, early=0.5, buffer_s=30.0, hold_s=60.0)
WAIT = {"command": "wait_for_flight"}


def navigate(north: float, east: float) -> dict:
    lat, lon = offset(*ORIGIN, north, east)
    return {"command": "navigate", "params": {"lat": lat, "lon": lon}}


def corner(*between: dict) -> list[dict]:
    """Climb at the origin, fly 300 m north, then 300 m east (`between` in between), land."""
    return [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 20}},
        WAIT,
        navigate(300, 0),
        *between,
        navigate(300, 300),
        {"command": "land"},
    ]


def diagonal_across(height: float) -> Reserved:
    """Another drone's level leg across the diagonal, 150 m north-east, from north-west
    to south-east: clear of both legs of the corner, on the shortcut's way."""
    a, b = offset(*ORIGIN, 200, 100), offset(*ORIGIN, 100, 200)
    leg = [*a, *b, height - 2.0, height + 2.0, T - 600.0, T + 600.0]
    return Reserved("other", "ACME_OTHER", 1, [leg], 2.0, 0.0, 0.0)


def conflict(steps: list[dict], other: Reserved):  # type: ignore[no-untyped-def]
    legs, _ = flight_legs(steps, (*ORIGIN, 0.0), T, PACE)
    return Airspace([other]).first_conflict(Flight(legs, 2.0, 0.0, 0.0)), legs


def test_the_shortcut_is_reserved_and_met_where_the_corner_is_not():
    clash, legs = conflict(corner(), diagonal_across(20.0))
    assert clash is not None and legs[clash.leg].step == 4  # the second navigate
    assert conflict(corner(WAIT), diagonal_across(20.0))[0] is None
    # A sleep waits a time, not an arrival: the corner may still be cut.
    slept = corner({"command": "sleep", "params": {"value": 5}})
    clash, legs = conflict(slept, diagonal_across(20.0))
    assert clash is not None and legs[clash.leg].step == 5
    # Out of its band it is clear: the fan's band is that of the unfinished moves.
    assert conflict(corner(), diagonal_across(60.0))[0] is None


def test_the_fan_runs_from_along_the_unfinished_leg_to_the_target_at_most_the_spacing_apart():
    legs, _ = flight_legs(corner(), (*ORIGIN, 0.0), T, PACE)
    second = [leg for leg in legs if leg.step == 4]
    planned, *fan = second
    target = offset(*ORIGIN, 300, 300)
    assert (planned.lat0, planned.lon0) == pytest.approx(offset(*ORIGIN, 300, 0))
    assert all((leg.lat1, leg.lon1) == pytest.approx(target) for leg in second)
    starts = sorted(ground_distance(*ORIGIN, leg.lat0, leg.lon0) for leg in fan)
    assert starts[0] == pytest.approx(0.0, abs=1e-6)  # the shortcut from the origin
    gaps = [b - a for a, b in zip([*starts, 300.0], [*starts, 300.0][1:], strict=False)]
    assert max(gaps) <= FAN_SPACING_M + 1e-6
    # Sent at once after the first navigate: the fan is there from then, not from the
    # end of the first leg, and until the shortcut's flight would end.
    first = next(leg for leg in legs if leg.step == 3)
    assert all(leg.t0 <= first.t0 for leg in fan)
    assert all(leg.t1 >= planned.t1 for leg in fan)


def test_cutting_the_corner_lets_the_later_legs_be_there_sooner():
    # Out 300 m north and straight back: cut short, the drone may be home at once, so the
    # landing there is reserved from (nearly) the start.
    there_and_back = [
        {"command": "takeoff", "params": {"altitude": 20}},
        WAIT,
        navigate(300, 0),
        navigate(0, 0),
        WAIT,
        {"command": "land"},
    ]
    legs, _ = flight_legs(there_and_back, (*ORIGIN, 0.0), T, PACE)
    landing = next(leg for leg in legs if leg.step == 5)
    climb = next(leg for leg in legs if leg.step == 0)
    # The climb takes 10 s: the landing may begin right after it (less the buffer).
    assert landing.t0 <= climb.t1 - PACE.buffer_s


def corner_mission(*between: dict) -> dict:
    """ACME_B from 150 m west of the origin: 300 m north, then 300 m east."""
    x, y = point_at(300, -150), point_at(300, 150)
    return {
        "name": "corner",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 20}},
            WAIT,
            {"command": "navigate", "params": {"lat": x[0], "lon": x[1]}},
            *between,
            {"command": "navigate", "params": {"lat": y[0], "lon": y[1]}},
            {"command": "land"},
        ],
    }


def test_a_conflict_only_on_the_shortcut_refuses_the_start_and_a_wait_clears_it(
    two_drones,  # noqa: F811
):
    world = two_drones
    # ACME_A north along the origin's meridian to 250 m north, where it lands; ACME_B's
    # corner passes 150 m west of it and 50 m north of its landing, its shortcut across it.
    first = start(world.operator, crossing((-150, 0), (250, 0), 20), "ACME_A")
    assert first.status_code == 200, first.json()
    refused = start(world.operator, corner_mission(), "ACME_B")
    assert refused.status_code == 409, refused.json()
    error = refused.json()
    assert error["code"] == "conflict" and "drone ACME_A" in error["error"], error
    assert not Assignment.objects.filter(drone__drone_id="ACME_B").exists()
    accepted = start(world.operator, corner_mission(WAIT), "ACME_B")
    assert accepted.status_code == 200, accepted.json()
    assert Reservation.objects.filter(ended_at__isnull=True).count() == 2


def test_a_burst_of_moves_reserves_one_fan_covering_every_shortcut():
    # Four navigates sent at once: the drone may be anywhere in their hull. Only the last
    # one's fan is reserved (it covers the others'), so the flight's legs stay few; the
    # first corner's shortcut is still met, named as the burst's last step.
    burst = [
        {"command": "takeoff", "params": {"altitude": 20}},
        WAIT,
        navigate(300, 0),
        navigate(300, 300),
        navigate(600, 300),
        navigate(600, 600),
        {"command": "land"},
    ]
    legs, _ = flight_legs(burst, (*ORIGIN, 0.0), T, PACE)
    per_step = {step: sum(leg.step == step for leg in legs) for step in (3, 4, 5)}
    assert per_step[3] == per_step[4] == 1 and per_step[5] > 1
    assert len(legs) <= 6 + 64  # takeoff, four legs, the landing and one fan at most
    clash, legs = conflict(burst, diagonal_across(20.0))
    assert clash is not None and legs[clash.leg].step == 5

"""A sideways move sent while the drone still climbs — a `navigate` straight after its
`takeoff`, no `wait_for_flight` between — is reserved on the slant it is flown on, in
pieces whose bands cover only the heights the drone can be at along them: on fixed
geometry a level leg met mid-slant conflicts and one under the slant's end does not; the
simulator's vehicle, sent its targets as the agent sends them, stays inside the
reservation; and a refused mission start names the step."""

from __future__ import annotations

import math

import pytest

from airspace import reservations, separation
from airspace.corridors import (
    EARTH_RADIUS,
    Leg,
    Pace,
    _moves,
    _Where,
    flight_legs,
    offset,
    slant_pieces,
)
from airspace.index import Airspace, Flight, Reserved, first_conflict_pairwise
from firmware.sim.receiver import ReceiverArming
from firmware.sim.vehicle import Vehicle, VehicleConfig
from onboard.arming_frames import load_frames
from onboard.mission import PacedLeg
from tests.missions.conftest import point_at

from .test_planner_check import check
from .test_separation import PLACE, crossing, start, two_drones  # noqa: F401

ORIGIN = (40.6303, -8.6575)
T = 1_800_000_000.0
PACE = Pace(speed_m_s=5.0, climb_m_s=2.0, slack=0.5, early=0.5, buffer_s=30.0, hold_s=60.0)
# The slowest climb (2 m/s / 1.5) at the fastest flight (5 m/s × 2): metres per metre.
SLOPE = (2.0 / 1.5) / 10.0


def navigate(north: float, east: float = 0.0, **params: float) -> dict:
    lat, lon = offset(*ORIGIN, north, east)
    return {"command": "navigate", "params": {"lat": lat, "lon": lon, **params}}


def slanted(altitude: float, north: float, *between: dict) -> list[dict]:
    """Take off at the origin to `altitude` and fly `north` metres, `between` in between."""
    return [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": altitude}},
        *between,
        navigate(north),
        {"command": "land"},
    ]


def across(north: float, height: float) -> Reserved:
    """Another drone's level leg from west to east `north` metres out, at `height`."""
    a, b = offset(*ORIGIN, north, -300.0), offset(*ORIGIN, north, 300.0)
    leg = [*a, *b, height - 2.0, height + 2.0, T - 600.0, T + 600.0]
    return Reserved("other", "ACME_OTHER", 1, [leg], 2.0, 30.0, 10.0)


def first_conflict(steps: list[dict], other: Reserved, height: float = 0.0):  # type: ignore[no-untyped-def]
    legs, _ = flight_legs(steps, (*ORIGIN, height), T, PACE)
    flight = Flight(legs, 2.0, 30.0, 10.0)
    clash = Airspace([other]).first_conflict(flight)
    plain = first_conflict_pairwise([other], flight)
    assert (clash is None) == (plain is None)
    if clash is not None:
        assert (clash.leg, clash.at) == (plain.leg, plain.at)  # type: ignore[union-attr]
    return clash, legs


def north_of(lat: float) -> float:
    return math.radians(lat - ORIGIN[0]) * EARTH_RADIUS


def test_a_level_leg_met_mid_slant_conflicts_where_climbing_first_would_not():
    # 60 m up and 800 m north at once: at 200 m out the drone may be as low as 26.7 m.
    clash, legs = first_conflict(slanted(60.0, 800.0), across(200.0, 25.0))
    assert clash is not None and legs[clash.leg].step == 2  # the navigate
    assert north_of(clash.lat) == pytest.approx(200.0, abs=1.0)
    # Climbed first (a wait for the climb), the leg is level at 60 m: clear of it.
    waited = slanted(60.0, 800.0, {"command": "wait_for_flight"})
    assert first_conflict(waited, across(200.0, 25.0))[0] is None


def test_a_level_leg_under_the_slants_end_and_above_its_start_does_not_conflict():
    # 600 m out every way of flying it is at 60 m (the slowest climb is done by 450 m).
    assert first_conflict(slanted(60.0, 800.0), across(600.0, 30.0))[0] is None
    # Where the drone can be at 30 m (it is at least 40 m up from 300 m out) it conflicts.
    assert first_conflict(slanted(60.0, 800.0), across(200.0, 30.0))[0] is not None
    # Within the minima of the slant's end it conflicts too: a drone may climb first.
    assert first_conflict(slanted(60.0, 800.0), across(600.0, 52.0))[0] is not None
    assert first_conflict(slanted(60.0, 800.0), across(60.0, 52.0))[0] is not None


def test_the_pieces_bands_follow_the_slowest_climb_at_the_fastest_flight():
    legs, _ = flight_legs(slanted(60.0, 800.0), (*ORIGIN, 0.0), T, PACE)
    (
        climb,
        *pieces,
        descent,
    ) = legs
    assert (climb.step, climb.low, climb.high) == (1, 0.0, 62.0)
    assert {p.step for p in pieces} == {2} and descent.step == 3
    # Contiguous from the origin to the target, each piece's band from the lowest height
    # at its start (less the tolerance) to the target's height (a drone may climb first).
    assert north_of(pieces[0].lat0) == pytest.approx(0.0, abs=1e-6)
    assert north_of(pieces[-1].lat1) == pytest.approx(800.0, abs=1e-6)
    for before, after in zip(pieces, pieces[1:], strict=False):
        assert (before.lat1, before.lon1) == (after.lat0, after.lon0)
    for piece in pieces:
        start, end = north_of(piece.lat0), north_of(piece.lat1)
        assert piece.high == 62.0
        assert piece.low == pytest.approx(max(0.0, min(60.0, SLOPE * start) - 2.0), abs=1e-6)
        # The lowest height rises by at most one step (the vertical minimum) along a piece.
        assert min(60.0, SLOPE * end) - min(60.0, SLOPE * start) <= 10.0 + 1e-6
    # Pieces end where the slowest climb passes each 10 m and where it reaches 60 m.
    ends = [north_of(p.lat1) for p in pieces]
    assert ends == pytest.approx([75.0, 150.0, 225.0, 300.0, 375.0, 450.0, 800.0], abs=1e-6)
    # Flown on the slant it may be there as soon as it was sent; climbing first, as late
    # as the level leg would be (10 s of climb, then 5 m/s).
    assert pieces[0].t0 == T - 30.0 and pieces[0].t1 == T + (30.0 + 15.0) * 1.5 + 30.0
    assert pieces[-1].t0 == pytest.approx(T + 450.0 / 5.0 * 0.5 - 30.0)
    assert pieces[-1].t1 == pytest.approx(T + (30.0 + 160.0) * 1.5 + 30.0)


def test_a_sleep_climbs_part_of_the_way_and_a_wait_for_flight_all_of_it():
    sleep = {"command": "sleep", "params": {"value": 15.0}}
    legs, _ = flight_legs(slanted(60.0, 800.0, sleep), (*ORIGIN, 0.0), T, PACE)
    pieces = [leg for leg in legs if leg.step == 3]
    # 15 s at the slowest climb: at least 20 m up before it leaves.
    assert pieces[0].low == pytest.approx(18.0) and north_of(pieces[0].lat1) == pytest.approx(75.0)
    # Long enough for the slowest climb, it leaves level, as after a wait for the climb.
    long_sleep = {"command": "sleep", "params": {"value": 45.0}}
    for between in (long_sleep, {"command": "wait_for_flight"}):
        legs, _ = flight_legs(slanted(60.0, 800.0, between), (*ORIGIN, 0.0), T, PACE)
        (level,) = [leg for leg in legs if leg.step == 3]
        assert (level.low, level.high) == (58.0, 62.0)
    # Steps that do not move it (a reading) leave the climb under way.
    sense = {"command": "sense", "params": {"sensor": "OUT_MEASURE"}}
    legs, _ = flight_legs(slanted(60.0, 800.0, sense), (*ORIGIN, 0.0), T, PACE)
    assert min(leg.low for leg in legs if leg.step == 3) == 0.0


def test_a_navigate_after_a_descent_in_place_is_reserved_on_its_way_down():
    steps = [{"command": "altitude", "params": {"value": -60.0}}, navigate(800.0)]
    legs, _ = flight_legs(steps, (*ORIGIN, 80.0), T, PACE)
    pieces = [leg for leg in legs if leg.step == 1]
    assert pieces[0].high == 82.0 and pieces[-1].high == 22.0
    assert {p.low for p in pieces} == {18.0}
    assert first_conflict(steps, across(600.0, 70.0), height=80.0)[0] is None
    assert first_conflict(steps, across(100.0, 70.0), height=80.0)[0] is not None


def test_heights_on_both_sides_of_the_climbs_start_are_reserved_whole():
    """Sent up 20 m and then, on the leg, 40 m down: the leg's band holds every height."""
    steps = [
        {"command": "altitude", "params": {"value": 20.0}},
        navigate(400.0, altitude_delta=-40.0),
    ]
    legs, _ = flight_legs(steps, (*ORIGIN, 40.0), T, PACE)
    (leg,) = [leg for leg in legs if leg.step == 1]
    assert (leg.low, leg.high) == (18.0, 62.0)


def test_slant_pieces_of_a_short_leg_reach_its_end_before_the_climb_ends():
    """A leg shorter than the slowest climb's slant: one piece per 10 m up to where it
    ends, the last reaching up to the target's height (the drone climbs over it)."""
    legs, _ = flight_legs(slanted(60.0, 100.0), (*ORIGIN, 0.0), T, PACE)
    pieces = [leg for leg in legs if leg.step == 2]
    assert [round(north_of(p.lat1), 6) for p in pieces] == [75.0, 100.0]
    assert [p.low for p in pieces] == [0.0, 8.0] and pieces[-1].high == 62.0


def _armed(max_horizontal: float, max_climb: float) -> Vehicle:
    frames = load_frames()
    config = VehicleConfig(max_horizontal=max_horizontal, max_climb=max_climb)
    vehicle = Vehicle(config=config, receiver=ReceiverArming(frames))
    for _ in range(round((frames.arming_time_s + 0.1) / 0.02)):
        vehicle.feed_receiver(frames.arm_frame_us)
        vehicle.step(0.02)
    assert vehicle.armed == "Armed"
    vehicle.set_flight_mode("PathPlanner")
    return vehicle


def _covered(legs: list[Leg], t: float, north: float, east: float, height: float) -> bool:
    for leg in legs:
        if not (leg.t0 <= t <= leg.t1 and leg.low <= height <= leg.high):
            continue
        a = (north_of(leg.lat0), _east_of(leg.lon0))
        b = (north_of(leg.lat1), _east_of(leg.lon1))
        dn, de = b[0] - a[0], b[1] - a[1]
        length2 = dn * dn + de * de
        u = 0.0 if length2 == 0 else ((north - a[0]) * dn + (east - a[1]) * de) / length2
        u = min(1.0, max(0.0, u))
        if math.hypot(north - a[0] - u * dn, east - a[1] - u * de) <= 2.0:  # the radius
            return True
    return False


def _east_of(lon: float) -> float:
    return math.radians(lon - ORIGIN[1]) * EARTH_RADIUS * math.cos(math.radians(ORIGIN[0]))


def _fly(
    vehicle: Vehicle, how: str, speed: float | None
) -> list[tuple[float, float, float, float]]:
    """The vehicle sent a take-off to 60 m and a leg 800 m north as the agent sends them:
    both at once (`slant`; a paced leg's target moved along it at `speed` as the agent
    paces it, held back for the climb as the agent holds it), or the take-off flown out
    first (`climb first`, an autopilot mission's take-off item). (seconds since the
    take-off was sent, north, east, height) every 0.5 s."""
    dt, samples, t = 0.05, [], 0.0
    vehicle.set_path_desired("Endpoint", (0.0, 0.0, -60.0))
    if how == "climb first":
        while vehicle.ned[2] > -59.9:
            vehicle.step(dt)
            t += dt
            samples.append((t, *vehicle.ned))
    leg = PacedLeg((0.0, 0.0, -60.0), (800.0, 0.0, -60.0), speed) if speed else None
    if leg is None:
        vehicle.set_path_desired("Endpoint", (800.0, 0.0, -60.0))
    while math.dist(vehicle.ned, (800.0, 0.0, -60.0)) > 0.5 and t < 600.0:
        if leg is not None:
            vehicle.set_path_desired("Endpoint", leg.advance(dt, tuple(vehicle.ned)))
        vehicle.step(dt)
        t += dt
        samples.append((t, *vehicle.ned))
    return [(s, n, e, -d) for s, n, e, d in samples[::10]]


@pytest.mark.parametrize(
    ("how", "max_horizontal", "max_climb", "speed"),
    [
        ("slant", 10.0, 2.0, None),  # the simulator's own speeds: twice the assumed cruise
        ("slant", 4.0, 1.5, None),  # slower on both axes
        ("slant", 10.0, 2.0, 8.0),  # a paced leg at 8 m/s: its target waits for the climb
        ("climb first", 10.0, 2.0, None),
    ],
)
def test_the_simulators_flight_stays_inside_its_reservation(how, max_horizontal, max_climb, speed):  # type: ignore[no-untyped-def]
    vehicle = _armed(max_horizontal, max_climb)
    extra = {"speed": speed} if speed else {}
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 60.0}}]
    steps.append(navigate(800.0, **extra))
    legs, _ = flight_legs(steps, (*ORIGIN, 0.0), T, PACE)
    samples = _fly(vehicle, how, speed)
    assert samples[-1][1] == pytest.approx(800.0, abs=6.0)
    outside = [s for s in samples if not _covered(legs, T + s[0], *s[1:])]
    assert not outside, outside[:5]
    if how == "slant" and speed is None:
        # Reserved as if it climbed first (the gap this closes), the slant is not covered.
        climbed = flight_legs([*steps[:2], {"command": "wait_for_flight"}, steps[2]], (*ORIGIN, 0.0), T, PACE)[0]  # fmt: skip
        assert any(not _covered(climbed, T + s[0], *s[1:]) for s in samples)


def test_slant_pieces_are_whole_and_ordered():
    """The shares cover the leg once, in order, for any climb and speed."""

    for altitude in (5.0, 33.0, 120.0):
        for north in (10.0, 250.0, 2000.0):
            steps = slanted(altitude, north)
            moves = [m for m in _moves(steps, _Where(*ORIGIN, 0.0, 0.0), PACE) if m.rise]
            (move,) = moves
            pieces = slant_pieces(move, PACE)
            assert pieces[0][0] == 0.0 and pieces[-1][1] == 1.0
            assert all(
                a[1] == b[0] and a[0] < a[1] for a, b in zip(pieces, pieces[1:], strict=False)
            )
            assert [p[2] for p in pieces] == sorted(p[2] for p in pieces)


@pytest.mark.django_db
def test_a_mission_leaving_on_a_slant_across_a_lower_corridor_is_refused_naming_its_step(
    two_drones,  # noqa: F811
):
    """ACME_A crosses the origin at 20 m; ACME_B, 150 m west of it, takes off to 40 m and
    flies east at once: it may still be climbing through 20 m over the origin."""
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    east = point_at(0, 150)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 40.0}},
        {"command": "navigate", "params": {"lat": east[0], "lon": east[1]}},
        {"command": "wait_for_flight"},
        {"command": "land"},
    ]
    planned = check(world.operator, steps, "ACME_B")["conflicts"]
    (conflict,) = planned
    # The step, and its whole leg (not the piece): from ACME_B's home to the target.
    assert conflict["step"] == 2 and conflict["drone"] == "ACME_A"
    home = point_at(0, -150)
    assert [*conflict["leg"][0], *conflict["leg"][1]] == pytest.approx([*home, *east], abs=1e-6)
    assert conflict["band_m"][0] < 22.0 + 10.0 and conflict["band_m"][1] == 42.0
    refused = start(world.operator, {"name": "slant", "steps": steps}, "ACME_B")
    assert refused.status_code == 409 and refused.json()["code"] == "conflict"
    error = refused.json()["error"]
    assert "Step 2: The flight comes within the separation minima" in error
    assert "drone ACME_A" in error
    lat, lon, _ = PLACE.search(error).groups()
    origin = point_at(0, 0)
    assert abs(float(lat) - origin[0]) < 1e-5 and abs(float(lon) - origin[1]) < 1e-5
    # Climbing to 40 m before it leaves, it crosses 20 m higher: accepted.
    waited = [*steps[:2], {"command": "wait_for_flight"}, *steps[2:]]
    assert check(world.operator, waited, "ACME_B")["conflicts"] == []
    accepted = start(world.operator, {"name": "climb first", "steps": waited}, "ACME_B")
    assert accepted.status_code == 200, accepted.json()


@pytest.mark.django_db
def test_a_navigate_command_sent_while_climbing_is_checked_on_its_slant(two_drones):  # noqa: F811
    """ACME_B, 5 m up over its home and still climbing to the 40 m its take-off asked
    for, is sent across ACME_A's corridor at 20 m, 150 m east: it may cross it climbing."""
    from fleet.models import Drone

    from .test_separation import client_for

    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    home, target = point_at(0, -150), point_at(0, 150)

    def send(alt: float):  # type: ignore[no-untyped-def]
        Drone.objects.filter(drone_id="ACME_B").update(
            airborne=True, alt=alt, home=list(home), lat=home[0], lon=home[1],
            nav_target=[0.0, 0.0, -40.0],
        )  # fmt: skip
        return client_for(world.operator).post(
            "/api/v1/drones/ACME_B/commands/",
            {"command": "navigate", "params": {"lat": target[0], "lon": target[1]}},
            format="json",
        )

    climbing = send(5.0)
    assert climbing.status_code == 409 and climbing.json()["code"] == "conflict"
    assert "drone ACME_A" in climbing.json()["error"]
    # Level at the height it reports, the leg would pass under ACME_A's band: the climb
    # under way is what meets it.
    drone = Drone.objects.get(drone_id="ACME_B")
    assert separation.climb_under_way(drone) == [{"command": "altitude", "params": {"value": 35.0}}]
    level = reservations.planned_legs(
        drone, [{"command": "navigate", "params": {"lat": target[0], "lon": target[1]}}]
    )
    others = reservations.others(drone.organisation, [drone.pk])
    separation.check_legs(drone, level[0], others)  # type: ignore[index]
    # Once at 40 m it crosses 20 m higher: not refused for separation.
    assert send(40.0).json().get("code") != "conflict"

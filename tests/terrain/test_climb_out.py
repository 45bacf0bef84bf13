"""A sideways leg sent while a climb is still under way — a `navigate` straight after its
`takeoff`, no `wait_for_flight` between them, or a command to a drone still climbing — is
flown on a slant from the height the drone is at: its terrain clearance is checked at the
height it has surely reached along it, least(d) = min(target, h0 + s·d), and while that is
below the minimum clearance the drone is climbing out (the terrain may not rise above
home). Through the REST API, on synthetic SRTM tiles written as the publishers write them."""

from __future__ import annotations

import re

import pytest

from airspace import reservations
from airspace.corridors import Pace
from fleet import envelopes
from fleet.models import CommandLog, Drone
from missions.models import Mission
from onboard.envelope import ned_to_latlon
from terrain.climbout import Climb, climb_slope
from terrain.guard import TerrainViolation, mission_climbs
from terrain.importer import import_path
from terrain.models import TerrainClearance

from .dem import GROUND, HOME, hill_tile, write_hgt
from .test_clearance import client_for

pytestmark = pytest.mark.django_db

# The 3 arc-second tile's rows are 92.8 m apart; home (40.6303) lies between row 444
# (33.4 m south of it) and row 443 (59.4 m north); row 442 is 152.2 m north of home.
RAMP_FOOT_M, RIDGE_M = 59.4, 152.2
RIDGE_RISE = 30.0
TARGET = ned_to_latlon(300.0, 0.0, HOME)
# Pace() defaults (no drone chosen): the slowest climb 2 m/s ÷ 1.5 = 1.33 m/s while flying
# at the fastest 5 m/s ÷ 0.5 = 10 m/s: 1 m up per 7.5 m along.
SLOPE = (2.0 / 1.5) / (5.0 / 0.5)


def north_of_home(row: int) -> float:
    dem = hill_tile()
    return (dem.latlon(row, 0)[0] - HOME[0]) * 111_319.49


def import_rows(terrain_dir, tmp_path, rows: dict[int, float]) -> None:  # type: ignore[no-untyped-def]
    """Flat ground at GROUND, and each row of `rows` (every column of it) raised by its rise."""
    dem = hill_tile()
    dem.samples[:] = GROUND
    for row, rise in rows.items():
        dem.samples[row, :] = GROUND + rise
    import_path(write_hgt(tmp_path, dem))


@pytest.fixture
def ridge(terrain_dir, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """From 59.4 m north of home the ground rises evenly to a plateau 30 m above home at
    152.2 m (row 442 and every row north of it)."""
    assert north_of_home(443) == pytest.approx(RAMP_FOOT_M, abs=0.1)
    assert north_of_home(442) == pytest.approx(RIDGE_M, abs=0.1)
    import_rows(terrain_dir, tmp_path, {row: RIDGE_RISE for row in range(400, 443)})


@pytest.fixture
def homed(world):  # type: ignore[no-untyped-def]
    """The organisation's missions are flown from HOME (its envelope's home)."""
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    return world


def mission(*between: dict) -> dict:
    """Take off at home to 40 m, `between`, fly 300 m north (over the ridge), land."""
    return {
        "name": "climb out",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 40}},
            *between,
            {"command": "navigate", "params": {"lat": TARGET[0], "lon": TARGET[1]}},
            {"command": "land"},
        ],
    }


def post(world, plan: dict):  # type: ignore[no-untyped-def]
    return client_for(world.operator).post("/api/v1/missions/", plan, format="json")


def test_a_leg_flown_while_climbing_meets_the_ridge_still_low(ridge, homed):
    """Minimum 5 m. Climbed first, the leg is level at 40 m: 10 m over the ridge, accepted.
    Sent at once, the drone is surely only 152.2 / 7.5 = 20.3 m up where the ridge is 30 m
    above home: about 10 m below its top, refused. (Its climb-out, below 5 m, ends 37.5 m
    out, before the ground rises at 59.4 m.)"""
    TerrainClearance.objects.create(organisation=homed.org, min_clearance=5.0)
    waited = post(homed, mission({"command": "wait_for_flight"}))
    assert waited.status_code == 201, waited.json()
    Mission.objects.all().delete()

    refused = post(homed, mission())
    assert refused.status_code == 409, refused.json()
    body = refused.json()
    assert body["code"] == "terrain_clearance"
    assert (
        "Step 2: The leg to the target is flown while the drone is still climbing" in body["error"]
    )
    assert "below the minimum terrain clearance of 5 m" in body["error"]
    found = re.search(r"(\d+) m along it, .* surely only ([\d.]+) m above home, ([\d.]+) m below", body["error"])  # fmt: skip
    assert found, body["error"]
    along, least, below = (float(v) for v in found.groups())
    # The lowest sample lies on the ramp or the plateau's edge, half a cell from its foot.
    assert RAMP_FOOT_M < along < RIDGE_M + 40.0
    assert least == pytest.approx(along * SLOPE, abs=0.1)
    assert 5.0 <= below <= RIDGE_RISE - RIDGE_M * SLOPE + 0.1
    assert not Mission.objects.exists()


def test_over_flat_ground_a_leg_flown_while_climbing_out_is_accepted(terrain_dir, tmp_path, homed):
    """Minimum 30 m: the drone is below it for the first 30 × 7.5 = 225 m of the leg, where
    the ground is no higher than home; then 30 m up or more over flat ground."""
    import_rows(terrain_dir, tmp_path, {})
    response = post(homed, mission())
    assert response.status_code == 201, response.json()
    assert response.json()["terrain_warnings"] == []


def test_ground_rising_above_home_while_climbing_out_is_refused(terrain_dir, tmp_path, homed):
    """A 5 m bank 59.4 m north of home: climbed first the leg passes over it at 40 m, sent at
    once the drone is surely only about 8 m up there, below the 30 m minimum, and the
    ground there is higher than home."""
    import_rows(terrain_dir, tmp_path, {443: 5.0})
    waited = post(homed, mission({"command": "wait_for_flight"}))
    assert waited.status_code == 201, waited.json()
    Mission.objects.all().delete()

    refused = post(homed, mission())
    assert refused.status_code == 409, refused.json()
    assert refused.json()["code"] == "terrain_clearance"
    error = refused.json()["error"]
    assert "Step 2: The leg to the target is flown while the drone is still climbing out" in error
    found = re.search(r"(\d+) m along it, .* only ([\d.]+) m above home, .* rises ([\d.]+) m above home's", error)  # fmt: skip
    assert found, error
    along, least, rise = (float(v) for v in found.groups())
    assert least == pytest.approx(along * SLOPE, abs=0.1) and least < 30.0
    assert 0.0 < rise <= 5.0


def test_the_refusal_states_the_clearance_and_the_minimum_that_applied(terrain_dir, tmp_path):
    """Climbing out, the minimum that applied is the height surely reached there."""
    import_rows(terrain_dir, tmp_path, {443: 5.0})
    steps = mission()["steps"]
    (found,) = envelopes.terrain.step_violations(None, HOME, steps, (0.0, 0.0, 0.0))
    violation = found.violation
    assert isinstance(violation, TerrainViolation) and found.index == 2
    assert 0.0 < violation.minimum < 30.0
    # The clearance is the height reached less the bank's rise above home there: under 5 m,
    # home itself lying 33.4 / 92.8 of the way up the bank's southern slope (1.8 m).
    assert 0.0 < violation.minimum - violation.clearance <= 5.0 + 0.1


def test_a_navigate_command_to_a_drone_still_climbing_is_judged_from_its_height(ridge, world):
    """5 m up over home and still climbing to the 40 m its take-off asked for, the drone is
    sent 300 m north over the ridge: at 152.2 m it is surely only 5 + 152.2·s m up (s at
    its pace, 1/7.5 m per m: 25.3 m), below the ridge's 30 m. At 40 m it passes 10 m over."""
    TerrainClearance.objects.create(organisation=world.org, min_clearance=5.0)

    def at(alt: float) -> Drone:
        Drone.objects.filter(pk=world.drone.pk).update(
            online=True, airborne=True, armed=True, lat=HOME[0], lon=HOME[1], alt=alt,
            battery_remaining=0.9, home=list(HOME), nav_target=[0.0, 0.0, -40.0],
        )  # fmt: skip
        return Drone.objects.get(pk=world.drone.pk)

    drone = at(5.0)
    slope = climb_slope(reservations.pace_for(drone))
    assert 5.0 + RIDGE_M * slope < RIDGE_RISE  # still below the plateau when it gets there
    params = {"lat": TARGET[0], "lon": TARGET[1]}
    response = client_for(world.operator).post(
        f"/api/v1/drones/{drone.drone_id}/commands/",
        {"command": "navigate", "params": params},
        format="json",
    )
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "terrain_clearance"
    assert "flown while the drone is still climbing" in response.json()["error"]
    assert CommandLog.objects.get().outcome == "rejected"
    # At the height of its target it is not climbing: the leg is level at 40 m.
    assert envelopes.check_command(at(40.0), "navigate", params) == []


def test_the_climb_under_way_is_tracked_step_by_step():
    """A climb in a mission starts from the level before it; a sleep is flown climbing at
    the slowest climb; a wait_for_flight ends the climb; a leg's own speed sets the slope."""
    north = [ned_to_latlon(n, 0.0, HOME) for n in (300.0, 600.0, 900.0)]
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 40}},
        {"command": "wait_for_flight"},
        {"command": "altitude", "params": {"value": 30}},
        {"command": "navigate", "params": {"lat": north[0][0], "lon": north[0][1]}},
        {"command": "altitude", "params": {"value": 20}},
        {"command": "sleep", "params": {"value": 6}},
        {"command": "navigate", "params": {"lat": north[1][0], "lon": north[1][1], "speed": 8}},
        {"command": "altitude", "params": {"value": 10}},
        {"command": "wait_for_flight"},
        {"command": "navigate", "params": {"lat": north[2][0], "lon": north[2][1]}},
    ]
    climbs = mission_climbs(HOME, steps, (0.0, 0.0, 0.0), Pace())
    assert set(climbs) == {4, 7}
    # The climb began over home (where the climb-out rule compares the terrain with).
    assert climbs[4] == Climb(40.0, pytest.approx(SLOPE), (0.0, 0.0))  # type: ignore[arg-type]
    # From 70 m, 6 s at the slowest climb (4/3 m/s): 78 m; 8 m/s at its fastest is 16 m/s.
    assert climbs[7].start == pytest.approx(78.0)
    assert climbs[7].slope == pytest.approx((2.0 / 1.5) / 16.0)
    # Slept long enough, the climb is done before the leg leaves: it is level.
    steps[6] = {"command": "sleep", "params": {"value": 15}}
    assert set(mission_climbs(HOME, steps, (0.0, 0.0, 0.0), Pace())) == {4}

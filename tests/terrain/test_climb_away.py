"""A climb away from home: the climb-out rule compares the terrain with the ground the
climb began over, not with home's. While the drone is less than the minimum clearance
above that ground (and below its target) the terrain may not rise above it; from there
the minimum holds. On synthetic SRTM tiles written as the publishers write them."""

from __future__ import annotations

import pytest

from airspace import reservations
from fleet import envelopes
from fleet.models import Drone
from onboard import envelope as env
from onboard.envelope import ned_to_latlon
from terrain import guard
from terrain.climbout import Climb, climb_slope
from terrain.importer import import_path

from .dem import GROUND, HOME, hill_tile, write_hgt
from .test_clearance import client_for
from .test_climb_out import import_rows, north_of_home

pytestmark = pytest.mark.django_db

# Row 436 is 708.7 m north of home, row 435 801.5 m; rows 92.8 m apart.
VALLEY_EDGE_M, RIM_M = 708.7, 801.5


def test_over_a_valley_a_climb_is_held_to_the_minimum_above_the_valleys_floor(
    terrain_dir, tmp_path, world
):
    """A valley 50 m deep ends at 708.7 m north of home, its side rising to home's level at
    801.5 m. The drone, 5 m above home (55 m above the valley floor) at 650 m north, still
    climbing to 60 m, is sent north to 950 m: at the rim, 151.5 m along, it is surely only
    about 25 m above home and so above the ground there, below the 30 m minimum. Judged
    against home's elevation (the ground never rises above home) it would be a climb-out
    and pass; the climb began 55 m above the valley floor, so the minimum holds."""
    assert north_of_home(436) == pytest.approx(VALLEY_EDGE_M, abs=0.1)
    assert north_of_home(435) == pytest.approx(RIM_M, abs=0.1)
    import_rows(terrain_dir, tmp_path, {row: -50.0 for row in range(436, 441)})
    over = ned_to_latlon(650.0, 0.0, HOME)

    def at(alt: float) -> Drone:
        Drone.objects.filter(pk=world.drone.pk).update(
            online=True, airborne=True, armed=True, lat=over[0], lon=over[1], alt=alt,
            battery_remaining=0.9, home=list(HOME), nav_target=[650.0, 0.0, -60.0],
        )  # fmt: skip
        return Drone.objects.get(pk=world.drone.pk)

    drone = at(5.0)
    climb = envelopes.command_climb(drone, "navigate", {})
    assert climb is not None and climb.origin == (650.0, 0.0)  # under its last target
    slope = climb.slope
    assert slope == pytest.approx(climb_slope(reservations.pace_for(drone)))
    assert 5.0 + (RIM_M - 650.0) * slope < 30.0  # below the minimum at the rim
    target = ned_to_latlon(950.0, 0.0, HOME)
    response = client_for(world.operator).post(
        f"/api/v1/drones/{drone.drone_id}/commands/",
        {"command": "navigate", "params": {"lat": target[0], "lon": target[1]}},
        format="json",
    )
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "terrain_clearance"
    error = response.json()["error"]
    assert "flown while the drone is still climbing:" in error, error
    assert "below the minimum terrain clearance of 30 m" in error
    # The same climb taken as begun over home passes: the old rule's blind spot.
    move = env.Move("goto", (950.0, 0.0, -60.0), True)
    over_home = Climb(5.0, slope)
    assessed = guard.move_assessment(None, HOME, (650.0, 0.0, -60.0), move, climb=over_home)
    assert assessed.violation is None
    # Done climbing, the leg is level at 60 m: 60 m over the rim.
    assert envelopes.check_command(at(60.0), "navigate", {"lat": target[0], "lon": target[1]}) == []


def test_a_mission_taking_off_again_on_a_plateau_climbs_out_over_the_plateau(terrain_dir, tmp_path):
    """A plateau 20 m above home from 337.7 m to 708.7 m north. The mission flies there at
    60 m, lands at 500 m north, takes off again to 60 m and at once flies on to 650 m
    north: climbing out over the plateau, which is flat, the terrain never rises above the
    ground the climb began over. Compared with home's elevation the plateau would be 20 m
    too high from the first metre."""
    import_rows(terrain_dir, tmp_path, {row: 20.0 for row in range(436, 441)})
    landing, beyond = ned_to_latlon(500.0, 0.0, HOME), ned_to_latlon(650.0, 0.0, HOME)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 60}},
        {"command": "wait_for_flight"},
        {"command": "navigate", "params": {"lat": landing[0], "lon": landing[1]}},
        {"command": "wait_for_flight"},
        {"command": "land"},
        {"command": "takeoff", "params": {"altitude": 60}},
        {"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}},
        {"command": "land"},
    ]
    start = (0.0, 0.0, 0.0)
    climbs = guard.mission_climbs(HOME, steps, start)
    assert set(climbs) == {7}
    assert climbs[7].origin == pytest.approx((500.0, 0.0))
    assert guard.step_violations(None, HOME, steps, start) == []
    # Taken as begun over home, the leg would be refused as climbing out over higher ground.
    over_home = {7: Climb(climbs[7].start, climbs[7].slope)}
    moves = guard.mission_moves(HOME, steps, start)
    (refused,) = guard.assess(None, HOME, moves, climbs=over_home).violations
    assert refused.index == 7 and "climbing out" in refused.violation.message


def test_a_mission_started_on_a_drone_still_climbing_flies_its_first_leg_on_that_climb(
    terrain_dir, tmp_path, world
):
    """5 m up over home, still climbing to 40 m: the mission's first leg leaves from 5 m
    on a slant, as a command would; a wait_for_flight first makes it level. Over a 5 m bank
    59.4 m north the slant passes below the 30 m minimum while the ground is above home."""
    import_rows(terrain_dir, tmp_path, {443: 5.0})
    north = ned_to_latlon(300.0, 0.0, HOME)
    leg = {"command": "navigate", "params": {"lat": north[0], "lon": north[1]}}
    start = (0.0, 0.0, -40.0)
    climbs = guard.mission_climbs(HOME, [leg], start, climbing_from=5.0)
    assert set(climbs) == {0} and climbs[0].start == 5.0 and climbs[0].origin == (0.0, 0.0)
    assert guard.mission_climbs(HOME, [{"command": "wait_for_flight"}, leg], start, climbing_from=5.0) == {}  # fmt: skip

    Drone.objects.filter(pk=world.drone.pk).update(
        online=True, airborne=True, armed=True, lat=HOME[0], lon=HOME[1], alt=5.0,
        battery_remaining=0.9, home=list(HOME), nav_target=list(start),
    )  # fmt: skip
    drone = Drone.objects.get(pk=world.drone.pk)
    (found,) = envelopes.step_violations(world.org, [leg], drone)
    assert found.index == 0 and "still climbing out" in found.violation.message
    assert envelopes.step_violations(world.org, [{"command": "wait_for_flight"}, leg], drone) == []


def test_a_corner_cut_by_a_leg_sent_before_the_last_one_ended_is_checked(
    terrain_dir, tmp_path, world
):
    """A block 100 m high 337–709 m north and 200–600 m east of home. The plan flies east
    800 m, then north 800 m, at 60 m: its legs as drawn pass beside the block. Sent one
    after the other without waiting, the second may be flown from anywhere along the first
    (its fan legs, onboard/envelope.py walk), straight across the block: refused, step 3.
    Waiting at each target, the drone flies the corner: accepted."""
    dem = hill_tile()
    dem.samples[:] = GROUND
    (north_row, west_col), (south_row, east_col) = (
        dem.sample_at(*ned_to_latlon(n, e, HOME)) for n, e in ((709.0, 200.0), (337.0, 600.0))
    )
    dem.samples[north_row : south_row + 1, west_col : east_col + 1] = GROUND + 100.0
    import_path(write_hgt(tmp_path, dem))
    east, corner = ned_to_latlon(0.0, 800.0, HOME), ned_to_latlon(800.0, 800.0, HOME)

    def plan(wait: bool) -> list[dict]:
        waited = [{"command": "wait_for_flight"}] if wait else []
        return [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 60}},
            *waited,
            {"command": "navigate", "params": {"lat": east[0], "lon": east[1]}},
            *waited,
            {"command": "navigate", "params": {"lat": corner[0], "lon": corner[1]}},
        ]

    start = (0.0, 0.0, 0.0)
    drawn = guard.mission_moves(HOME, plan(False), start)
    walked = guard.mission_moves(HOME, plan(False), start, shortcuts=True)
    assert len(walked) > len(drawn) == 3
    assert walked == [(i, m, s) for i, m, s, _ in env.walk(HOME, plan(False), start, False)]
    (found,) = guard.step_violations(None, HOME, plan(False), start)
    assert found.index == 3 and found.violation.code == "terrain_clearance"
    assert guard.step_violations(None, HOME, plan(True), start) == []

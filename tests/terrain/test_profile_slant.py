"""The planner's height profile of a leg flown while a climb is under way (a `navigate`
straight after its `takeoff`): the low edge the drone has surely reached along it,
min(target, h0 + s·d), and its clearance held as the terrain check holds it, through the
planner's check (REST API), on synthetic SRTM tiles written as the publishers write them."""

from __future__ import annotations

import re

import pytest

from fleet import envelopes
from onboard.envelope import ned_to_latlon
from terrain.models import TerrainClearance

from .dem import HOME
from .test_clearance import client_for
from .test_climb_out import RIDGE_M, RIDGE_RISE, SLOPE, TARGET, import_rows, north_of_home

pytestmark = pytest.mark.django_db

CLIMB = 30.0  # the take-off's target: reached 30 × 7.5 = 225 m along the 300 m leg


def steps(*between: dict) -> list[dict]:
    """Take off at home to 30 m, `between`, fly 300 m north, land."""
    return [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": CLIMB}},
        *between,
        {"command": "navigate", "params": {"lat": TARGET[0], "lon": TARGET[1]}},
        {"command": "land"},
    ]


def check(world, plan: list[dict]) -> dict:  # type: ignore[no-untyped-def]
    response = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", {"steps": plan}, format="json"
    )
    assert response.status_code == 200, response.json()
    return response.json()


@pytest.fixture
def homed(world):  # type: ignore[no-untyped-def]
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    return world


@pytest.fixture
def ridge(terrain_dir, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """From 59.4 m north of home the ground rises to a plateau 30 m above home at 152.2 m."""
    import_rows(terrain_dir, tmp_path, {row: RIDGE_RISE for row in range(400, 443)})


def test_a_leg_flown_while_climbing_over_rising_ground_shows_its_low_edge(ridge, homed):
    """Minimum 5 m: the drone climbs out for 5 × 7.5 = 37.5 m, reaches its 30 m at 225 m
    and flies level to 300 m. At the ridge's edge (152.2 m) it is surely only 20.3 m up,
    about 9.7 m below the plateau: the lowest clearance, and the check refuses the leg."""
    TerrainClearance.objects.create(organisation=homed.org, min_clearance=5.0)
    answer = check(homed, steps())
    profile = answer["profile"]
    assert profile["minimum_clearance_m"] == 5.0
    (slant,) = profile["slants"]
    assert slant["index"] == 2
    assert slant["from_m"] == 0.0 and slant["to_m"] == pytest.approx(300.0, abs=0.5)
    assert slant["level_m"] == [CLIMB, CLIMB]
    expected = [[0.0, 0.0], [5.0 / SLOPE, 5.0], [CLIMB / SLOPE, CLIMB], [300.0, CLIMB]]
    assert slant["edge"] == [[pytest.approx(d, abs=0.2), pytest.approx(h, abs=0.1)] for d, h in expected]  # fmt: skip
    assert slant["climbing_out_to_m"] == pytest.approx(37.5, abs=0.1)
    # The clearance on the edge is lowest where the ground stops rising (to the nearest
    # sample, half a cell apart), and it is the one the check states.
    assert RIDGE_M <= slant["lowest_at_m"] < RIDGE_M + 40.0
    lowest = slant["lowest_clearance_m"]
    assert lowest == pytest.approx(slant["lowest_at_m"] * SLOPE - RIDGE_RISE, abs=0.2)
    assert slant["climb_out_rise_m"] == pytest.approx(0.0, abs=0.05)
    assert slant["refused"] is True
    (violation,) = answer["violations"]
    assert violation["index"] == 2
    assert "flown while the drone is still climbing" in violation["message"]
    stated = re.search(r"([\d.]+) m below the terrain", violation["message"])
    assert stated and float(stated.group(1)) == pytest.approx(-lowest, abs=0.1), violation
    # The level path drawn is still the straight line at the take-off's height.
    assert [s["height_m"] for s in profile["steps"]] == [CLIMB, CLIMB, 0.0]


def test_after_wait_for_flight_the_leg_is_level(ridge, homed):
    """Climbed first, the leg flies level at 30 m: no low edge, and it passes the plateau
    with the height to spare the level path shows (the minimum of 0 m holds)."""
    TerrainClearance.objects.create(organisation=homed.org, min_clearance=0.0)
    answer = check(homed, steps({"command": "wait_for_flight"}))
    assert answer["profile"]["slants"] == []
    assert answer["violations"] == []


@pytest.mark.parametrize(("bank", "refused"), [(0.0, False), (5.0, True)])
def test_climbing_out_the_terrain_may_not_rise_above_home(terrain_dir, tmp_path, homed, bank, refused):  # fmt: skip
    """Minimum 30 m: the drone climbs out for the whole climb (to 225 m). Over flat ground
    the leg is flown; a 5 m bank 59.4 m north of home rises above home while the drone is
    surely only about 8 m up, and the profile marks the leg as the check refuses it."""
    assert north_of_home(443) == pytest.approx(59.4, abs=0.1)
    import_rows(terrain_dir, tmp_path, {443: bank} if bank else {})
    answer = check(homed, steps())
    (slant,) = answer["profile"]["slants"]
    assert slant["climbing_out_to_m"] == pytest.approx(CLIMB / SLOPE, abs=0.2)
    assert slant["edge"][:2] == [[0.0, 0.0], [pytest.approx(CLIMB / SLOPE, abs=0.2), CLIMB]]
    assert slant["refused"] is refused
    assert bool(answer["violations"]) is refused
    if refused:
        # Home lies a third of the way up the bank's southern slope: the rise above it is less.
        assert 0.0 < slant["climb_out_rise_m"] <= bank
    else:
        assert slant["climb_out_rise_m"] == pytest.approx(0.0, abs=0.05)
        # Level from 225 m: 30 m over flat ground, the minimum.
        assert slant["lowest_clearance_m"] == pytest.approx(CLIMB, abs=0.1)


def test_a_climb_over_the_plateau_is_marked_as_the_check_judges_it(ridge, homed):
    """Climbed first to 40 m, the drone flies 200 m north onto the plateau (30 m above home)
    and, once there (a leg sent earlier could cut across the ramp: its fan legs), climbs in
    place 20 m more, to 60 m, and, without waiting, flies on 100 m: that leg is flown while
    climbing from 40 m over ground 30 m above home, and the profile marks it as the terrain
    check judges it."""
    on, beyond = (ned_to_latlon(n, 0.0, HOME) for n in (200.0, 300.0))
    plan = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 40}},
        {"command": "wait_for_flight"},
        {"command": "navigate", "params": {"lat": on[0], "lon": on[1]}},
        {"command": "wait_for_flight"},
        {"command": "altitude", "params": {"value": 20}},
        {"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}},
        {"command": "land"},
    ]
    answer = check(homed, plan)
    (slant,) = answer["profile"]["slants"]
    assert slant["index"] == 6
    assert slant["from_m"] == pytest.approx(200.0, abs=0.5)
    assert slant["edge"][0] == [pytest.approx(200.0, abs=0.5), 40.0]
    assert slant["edge"][-1] == [pytest.approx(300.0, abs=0.5), pytest.approx(40 + 100 * SLOPE, abs=0.1)]  # fmt: skip
    assert slant["level_m"] == [60.0, 60.0]
    assert slant["refused"] is (6 in [v["index"] for v in answer["violations"]])
    # Less than the minimum (30 m) above the plateau the climb began over, the drone climbs
    # out the whole leg, over ground no higher than the plateau: flown. (Held to home's
    # ground, it would be only 10 m over the plateau, below the minimum.)
    assert slant["climbing_out_to_m"] == pytest.approx(300.0, abs=0.5)
    assert slant["climb_out_rise_m"] == pytest.approx(0.0, abs=0.05)
    assert slant["refused"] is False

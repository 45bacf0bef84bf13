"""Drone commands held to the terrain clearance, against a drone answering over MQTT: a
navigate through a hill is refused unsent (409 terrain_clearance), one over flat ground
is sent, and a command whose clearance cannot be checked says so in its answer."""

from __future__ import annotations

import pytest

from fleet.models import Drone
from onboard.envelope import ned_to_latlon
from terrain.importer import import_path
from tests.terrain.dem import HOME, hill_tile, write_hgt

from .test_envelope import HOME as FLYING_HOME
from .test_envelope import command
from .test_envelope import flying as flying  # the fixture: ACME_1 airborne, answering


@pytest.fixture
def terrain_dir(settings, tmp_path):  # type: ignore[no-untyped-def]
    settings.TERRAIN_DIR = str(tmp_path / "terrain")
    return tmp_path


def at_60_m() -> None:
    Drone.objects.filter(drone_id="ACME_1").update(alt=60.0, nav_target=[0.0, 0.0, -60.0])


def test_without_terrain_the_answer_says_the_clearance_was_not_checked(
    world_tx, flying, terrain_dir
):
    lat, lon = ned_to_latlon(100.0, 0.0, FLYING_HOME)
    response = command(world_tx.operator, "navigate", lat=lat, lon=lon)
    assert response.status_code == 200, response.content
    (warning,) = response.json()["terrain_warnings"]
    assert warning["step"] is None and "No terrain at home" in warning["message"]
    assert len(flying.requests) == 1


def test_a_navigate_through_the_hill_is_refused_unsent(world_tx, terrain_dir, request):
    flying = request.getfixturevalue("flying")
    assert tuple(FLYING_HOME) == HOME
    import_path(write_hgt(terrain_dir, hill_tile()))
    at_60_m()
    lat, lon = ned_to_latlon(900.0, 0.0, HOME)
    response = command(world_tx.operator, "navigate", lat=lat, lon=lon)
    assert response.status_code == 409, response.content
    assert response.json()["code"] == "terrain_clearance"
    assert "below the minimum terrain clearance of 30 m" in response.json()["error"]
    assert flying.requests == []
    # Over flat ground 60 m up (50 m above the terrain there) it is sent, with no warning.
    lat, lon = ned_to_latlon(-300.0, 0.0, HOME)
    response = command(world_tx.operator, "navigate", lat=lat, lon=lon)
    assert response.status_code == 200, response.content
    assert "terrain_warnings" not in response.json()
    assert [r["command"] for r in flying.requests] == ["navigate"]

"""What the planner's check answers besides the envelope: the leg of a plan that would
meet another drone's reservation (for the chosen drone, nothing kept), and the plan's
height profile over the imported terrain."""

from __future__ import annotations

import pytest

from airspace.models import Reservation
from fleet import envelopes
from onboard.envelope import ned_to_latlon
from terrain.importer import import_path
from tests.missions.conftest import online_drone, point_at
from tests.terrain.dem import GROUND, HILL, HOME, hill_tile, write_hgt

from .test_separation import client_for, crossing, start

pytestmark = pytest.mark.django_db


def check(user, steps: list, drone: str | None = None) -> dict:  # type: ignore[no-untyped-def]
    response = client_for(user).post(
        "/api/v1/missions/check-envelope/", {"steps": steps, "drone": drone}, format="json"
    )
    assert response.status_code == 200, response.json()
    return response.json()


@pytest.fixture
def two_drones(world):  # type: ignore[no-untyped-def]
    online_drone(world.org, "ACME_A", north=-150)
    online_drone(world.org, "ACME_B", east=-150)
    return world


def test_a_plan_across_another_drones_corridor_names_it_and_its_leg(two_drones):
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    kept = Reservation.objects.count()
    answer = check(world.operator, crossing((0, -150), (0, 150), 20)["steps"], "ACME_B")
    (conflict,) = answer["conflicts"]
    assert conflict["drone"] == "ACME_A"
    assert "drone ACME_A" in conflict["message"]
    origin = point_at(0, 0)
    assert conflict["at"] == pytest.approx(list(origin), abs=1e-5)
    west, east = point_at(0, -150), point_at(0, 150)
    assert [*conflict["leg"][0], *conflict["leg"][1]] == pytest.approx([*west, *east], abs=1e-6)
    # The check keeps nothing: no reservation for ACME_B.
    assert Reservation.objects.count() == kept
    clear = check(world.operator, crossing((0, -150), (0, 150), 40)["steps"], "ACME_B")
    assert clear["conflicts"] == []


def test_without_a_drone_there_is_no_conflict_to_find(two_drones):
    world = two_drones
    start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A")
    assert check(world.operator, crossing((0, -150), (0, 150), 20)["steps"])["conflicts"] == []


def test_the_height_profile_shows_the_hill_under_the_leg(world, settings, tmp_path):
    settings.TERRAIN_DIR = str(tmp_path / "terrain")
    import_path(write_hgt(tmp_path, hill_tile()))
    envelopes.set_envelope(world.org, {"home": list(HOME), "max_height": 400, "max_distance": 2000})  # fmt: skip
    beyond = ned_to_latlon(1200.0, 0.0, HOME)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 250}},
        {"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}},
        {"command": "land"},
    ]
    profile = check(world.operator, steps)["profile"]
    assert profile["terrain"] is True
    assert profile["home_ground_m"] == pytest.approx(GROUND)
    distance, height, ground = profile["distance_m"], profile["height_m"], profile["ground_m"]
    assert len(distance) == len(height) == len(ground) >= 100
    assert distance[-1] == pytest.approx(1200.0, rel=1e-3)
    # The hill top lies 600 m along, HILL metres above the ground at home.
    top = max(range(len(ground)), key=lambda i: ground[i])
    assert distance[top] == pytest.approx(600.0, abs=50.0)
    assert ground[top] == pytest.approx(HILL, abs=2.0)
    assert height[top] == pytest.approx(250.0)
    assert [s["index"] for s in profile["steps"]] == [1, 2, 3]


def test_without_terrain_the_profile_has_heights_and_no_ground(world, settings, tmp_path):
    settings.TERRAIN_DIR = str(tmp_path / "terrain")
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    steps = crossing((0, 0), (0, 300), 20)["steps"]
    profile = check(world.operator, steps)["profile"]
    assert profile["terrain"] is False and profile["home_ground_m"] is None
    assert set(profile["ground_m"]) == {None}
    assert max(profile["height_m"]) == pytest.approx(20.0)

"""The envelope's maximum height read above the terrain: with an organisation's choice (or
TERRAIN_CEILING_ABOVE_TERRAIN), a leg that rises more than the maximum height above the
ground under it — flown out from a hill top over the plain — is refused with 409
`outside_envelope`, while the same leg without that choice, and a leg over level ground,
are accepted; a drone already higher above the terrain than that may fly on and down."""

from __future__ import annotations

import re

import pytest
from rest_framework.test import APIClient

import terrain
from fleet import envelopes
from fleet.models import Drone
from missions.models import Mission
from onboard.envelope import ned_to_latlon
from terrain.importer import import_path
from terrain.models import TerrainClearance

from .dem import GROUND, HILL, HOME, write_hgt

pytestmark = pytest.mark.django_db


@pytest.fixture
def hill_top(terrain_dir, tmp_path, hill, world) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """The hill imported and the organisation's home on its top, 200 m above the plain."""
    import_path(write_hgt(tmp_path, hill))
    top = hill.hill_top()
    envelopes.set_envelope(world.org, {"home": list(top)})
    return top


def ceiling_above_terrain(world) -> None:  # type: ignore[no-untyped-def]
    TerrainClearance.objects.create(
        organisation=world.org, min_clearance=30.0, ceiling_above_terrain=True
    )


def out_to(home: tuple[float, float], north: float, altitude: float) -> dict:
    """Take off at `home` to `altitude`, fly `north` metres north at that height, land."""
    far = ned_to_latlon(north, 0.0, home)
    return {
        "name": "out from home",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "navigate", "params": {"lat": far[0], "lon": far[1]}},
            {"command": "land"},
        ],
    }


def post_mission(user, body: dict):  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client.post("/api/v1/missions/", body, format="json")


def test_the_highest_clearance_of_a_leg_and_its_start_are_found(terrain_dir, tmp_path, hill):
    import_path(write_hgt(tmp_path, hill))
    top = hill.hill_top()
    plain = ned_to_latlon(600.0, 0.0, top)
    found = terrain.clearance_along((*top, 310.0), (*plain, 310.0))
    assert found.at_start == pytest.approx(100.0, abs=0.5)
    assert found.highest == pytest.approx(300.0, abs=0.5)
    # Highest over the plain: beyond the hill's 450 m radius.
    assert found.highest_at is not None and found.highest_at[2] >= 440.0
    assert found.minimum == pytest.approx(100.0, abs=0.5)


def test_a_leg_out_over_the_plain_is_refused_when_the_ceiling_is_above_terrain(hill_top, world):
    ceiling_above_terrain(world)
    response = post_mission(world.operator, out_to(hill_top, 600.0, 100.0))
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "outside_envelope", body
    found = re.search(r"Step 2: The straight leg to the target rises to ([\d.]+) m above", body["error"])  # fmt: skip
    assert found and float(found.group(1)) == pytest.approx(HILL + 100.0, abs=1.0), body
    assert "above the envelope's maximum height of 120 m above the terrain" in body["error"]
    assert not Mission.objects.exists()


def test_the_planner_marks_the_leg_with_its_limit(hill_top, world):
    ceiling_above_terrain(world)
    client = APIClient()
    client.force_authenticate(world.operator)
    steps = out_to(hill_top, 600.0, 100.0)["steps"]
    check = client.post("/api/v1/missions/check-envelope/", {"steps": steps}, format="json")
    assert check.status_code == 200, check.json()
    (row,) = check.json()["violations"]
    assert (row["index"], row["limit"]) == (2, "max_height_agl")
    assert row["leg"][0] == pytest.approx(list(hill_top))


def test_without_the_choice_the_ceiling_is_above_home_only(hill_top, world):
    response = post_mission(world.operator, out_to(hill_top, 600.0, 100.0))
    assert response.status_code == 201, response.json()


def test_the_site_wide_default_applies_to_an_organisation_without_its_own(
    hill_top, world, settings
):
    settings.TERRAIN_CEILING_ABOVE_TERRAIN = True
    response = post_mission(world.operator, out_to(hill_top, 600.0, 100.0))
    assert response.status_code == 409 and response.json()["code"] == "outside_envelope"
    # An organisation's own choice wins over the default.
    TerrainClearance.objects.create(organisation=world.org, min_clearance=30.0)
    response = post_mission(world.operator, out_to(hill_top, 600.0, 100.0))
    assert response.status_code == 201, response.json()


def test_over_level_ground_the_same_height_is_flown(terrain_dir, tmp_path, hill, world):
    import_path(write_hgt(tmp_path, hill))
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    ceiling_above_terrain(world)
    # South of home, away from the hill: 110 m above the plain at 10 m.
    response = post_mission(world.operator, out_to(HOME, -500.0, 110.0))
    assert response.status_code == 201, response.json()
    assert terrain.elevation(*ned_to_latlon(-500.0, 0.0, HOME)) == pytest.approx(GROUND)


@pytest.fixture
def over_the_plain(hill_top, world) -> Drone:  # type: ignore[no-untyped-def]
    """The drone took off from the hill top and hovers 500 m north of it, 60 m above
    home: 260 m above the plain, higher than the ceiling already."""
    ceiling_above_terrain(world)
    here = ned_to_latlon(500.0, 0.0, hill_top)
    Drone.objects.filter(pk=world.drone.pk).update(
        online=True, airborne=True, armed=True, lat=here[0], lon=here[1], alt=60.0,
        battery_remaining=0.9, home=list(hill_top), nav_target=[500.0, 0.0, -60.0],
    )  # fmt: skip
    return Drone.objects.get(pk=world.drone.pk)


def test_a_climb_above_the_ceiling_over_the_terrain_is_refused(over_the_plain):
    with pytest.raises(envelopes.OutsideEnvelope) as refused:
        envelopes.check_command(over_the_plain, "altitude", {"value": 10})
    assert refused.value.code == "outside_envelope" and refused.value.limit == "max_height_agl"
    assert "The target is 270.0 m above the terrain" in refused.value.message


def test_a_drone_above_the_ceiling_may_fly_on_at_its_height_and_down(over_the_plain):
    further = ned_to_latlon(600.0, 0.0, tuple(over_the_plain.home))
    assert (
        envelopes.check_command(over_the_plain, "navigate", {"lat": further[0], "lon": further[1]})
        == []
    )
    assert envelopes.check_command(over_the_plain, "altitude", {"value": -10}) == []

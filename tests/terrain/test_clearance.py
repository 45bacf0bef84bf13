"""The minimum terrain clearance: legs sampled densely enough to see a ridge between
waypoints, refused through the REST API with 409 `terrain_clearance`, and legs or homes
without terrain (or over voids) reported, never passed over in silence."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from rest_framework.test import APIClient

import terrain
from fleet import envelopes
from fleet.models import CommandLog, Drone
from missions.models import Mission
from onboard.envelope import ned_to_latlon
from terrain.importer import import_path
from terrain.models import TerrainClearance

from .dem import GROUND, HILL_NORTH, HOME, Dem, hill_tile, with_void, write_hgt

pytestmark = pytest.mark.django_db
BEYOND_HILL = ned_to_latlon(2 * HILL_NORTH, 0.0, HOME)
# Within the default envelope's 1000 m of home, still past the hill top.
PAST_TOP = ned_to_latlon(900.0, 0.0, HOME)


@pytest.fixture
def hill_imported(terrain_dir, tmp_path, hill) -> Dem:  # type: ignore[no-untyped-def]
    import_path(write_hgt(tmp_path, hill))
    return hill


@pytest.fixture
def high_envelope(world):  # type: ignore[no-untyped-def]
    """The organisation may fly 400 m high (beyond the defaults, with a confirmation)."""
    envelopes.set_envelope(world.org, {"max_height": 400, "max_distance": 2000, "home": list(HOME)})
    return world


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def over_the_hill(altitude: float) -> dict:
    """Take off at home to `altitude`, fly north over the hill top at that height once
    there (sent at once, the leg would be flown climbing: tests/terrain/test_climb_out.py),
    land."""
    return {
        "name": "over the hill",
        "confirm_beyond_defaults": True,
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": BEYOND_HILL[0], "lon": BEYOND_HILL[1]}},
            {"command": "land"},
        ],
    }


# -- the lookup ------------------------------------------------------------------------------


def test_the_lowest_clearance_of_a_leg_is_found_at_the_hill_top(hill_imported):
    start, end = (*HOME, GROUND + 50.0), (*BEYOND_HILL, GROUND + 50.0)
    found = terrain.clearance_along(start, end)
    assert found.minimum == pytest.approx(GROUND + 50.0 - 210.0, abs=0.5)
    lat, lon, along = found.at  # type: ignore[misc]
    assert (lat, lon) == pytest.approx(hill_imported.hill_top(), abs=hill_imported.step / 2)
    assert along == pytest.approx(HILL_NORTH, abs=60)
    # Samples no farther apart than half the smallest cell (3 arc-seconds of longitude).
    cell_east = hill_imported.step * 111_319.49 * np.cos(np.radians(HOME[0]))
    assert found.spacing_m <= cell_east / 2 + 1e-6
    assert found.samples >= found.length_m / (cell_east / 2)
    assert found.gaps == []


def test_a_ridge_between_two_waypoints_is_seen(terrain_dir, tmp_path):
    """One row of samples 300 m high crossing a 6 km leg: both ends are over flat ground,
    the leg's middle is not."""
    dem = hill_tile()
    dem.samples[:] = GROUND
    row, _ = dem.sample_at(*ned_to_latlon(3000.0, 0.0, HOME))
    dem.samples[row, :] = 300
    import_path(write_hgt(tmp_path, dem))
    start, end = (*HOME, 200.0), (*ned_to_latlon(6000.0, 350.0, HOME), 200.0)
    assert terrain.elevation(*start[:2]) == terrain.elevation(*end[:2]) == pytest.approx(GROUND)
    found = terrain.clearance_along(start, end)
    # Half-cell sampling comes within a quarter cell of the ridge line: at least 3/4 of it.
    assert found.minimum <= 200.0 - (GROUND + 0.75 * (300 - GROUND))
    assert found.at[2] == pytest.approx(3000.0, abs=100)  # type: ignore[index]


def test_voids_and_missing_terrain_under_a_leg_are_reported(terrain_dir, tmp_path, hill):
    middle = ned_to_latlon(300.0, 0.0, HOME)
    import_path(write_hgt(tmp_path, with_void(hill, *middle)))
    found = terrain.clearance_along((*HOME, 300.0), (*BEYOND_HILL, 300.0))
    assert [g.reason for g in found.gaps] == ["void"]
    gap = found.gaps[0]
    assert gap.start_m < 300.0 < gap.end_m and gap.end_m - gap.start_m < 600
    # The clearance is still found where there is terrain.
    assert found.minimum == pytest.approx(300.0 - 210.0, abs=0.5)
    # Off the tile's north edge (latitude 41) and the outer half of its edge cells there
    # is no terrain at all.
    off = terrain.clearance_along((40.99, -8.5, 300.0), (41.01, -8.5, 300.0))
    assert [g.reason for g in off.gaps] == ["no terrain"]
    half_cell_m = hill.step / 2 * 111_195
    assert off.gaps[0].start_m == pytest.approx(1113 + half_cell_m, abs=off.spacing_m)


# -- enforcement through the API ---------------------------------------------------------------


def test_a_leg_through_the_hill_is_refused_with_409_terrain_clearance(hill_imported, high_envelope):
    response = client_for(high_envelope.operator).post(
        "/api/v1/missions/", over_the_hill(50.0), format="json"
    )
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "terrain_clearance"
    found = re.search(
        r"Step 3: The straight leg to the target passes ([\d.]+) m below the terrain", body["error"]
    )
    assert found and float(found.group(1)) == pytest.approx(150.0, abs=1.0), body["error"]
    assert "below the minimum terrain clearance of 30 m" in body["error"]
    assert not Mission.objects.exists()


def test_the_same_leg_high_enough_is_accepted(hill_imported, high_envelope):
    client = client_for(high_envelope.operator)
    response = client.post("/api/v1/missions/", over_the_hill(250.0), format="json")
    assert response.status_code == 201, response.json()
    assert response.json()["terrain_warnings"] == []
    check = client.post(
        "/api/v1/missions/check-envelope/", {"steps": over_the_hill(50.0)["steps"]}, format="json"
    )
    assert check.status_code == 200
    (row,) = check.json()["violations"]
    assert (row["index"], row["limit"]) == (3, "terrain_clearance")
    assert row["leg"][0] == pytest.approx(list(HOME))


def test_an_organisations_own_minimum_applies(hill_imported, high_envelope):
    TerrainClearance.objects.create(organisation=high_envelope.org, min_clearance=60.0)
    response = client_for(high_envelope.operator).post(
        "/api/v1/missions/", over_the_hill(250.0), format="json"
    )
    assert response.status_code == 409
    assert response.json()["code"] == "terrain_clearance"
    found = re.search(r"passes ([\d.]+) m above the terrain", response.json()["error"])
    assert found and float(found.group(1)) == pytest.approx(50.0, abs=1.0)
    assert "minimum terrain clearance of 60 m" in response.json()["error"]
    # Another organisation keeps the default.
    assert TerrainClearance.objects.count() == 1


def test_a_navigate_command_through_the_hill_is_refused(hill_imported, world):
    Drone.objects.filter(pk=world.drone.pk).update(
        online=True, airborne=True, armed=True, lat=HOME[0], lon=HOME[1], alt=60.0,
        battery_remaining=0.9, home=list(HOME), nav_target=[0.0, 0.0, -60.0],
    )  # fmt: skip
    response = client_for(world.operator).post(
        f"/api/v1/drones/{world.drone.drone_id}/commands/",
        {"command": "navigate", "params": {"lat": PAST_TOP[0], "lon": PAST_TOP[1]}},
        format="json",
    )
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "terrain_clearance", response.json()
    assert "minimum terrain clearance of 30 m" in response.json()["error"]
    assert CommandLog.objects.get().outcome == "rejected"
    # A descent in place over flat ground below the minimum is refused too.
    response = client_for(world.operator).post(
        f"/api/v1/drones/{world.drone.drone_id}/commands/",
        {"command": "altitude", "params": {"value": -45}},
        format="json",
    )
    assert response.status_code == 409
    assert "The target is 15.0 m above the terrain" in response.json()["error"]


def test_without_terrain_the_old_rule_applies_and_says_so(terrain_dir, world):
    client = client_for(world.operator)
    steps = over_the_hill(50.0)["steps"]
    response = client.post("/api/v1/missions/", {"name": "flat", "steps": steps}, format="json")
    assert response.status_code == 201, response.json()
    (warning,) = response.json()["terrain_warnings"]
    assert warning["step"] is None and "No terrain at home" in warning["message"]
    check = client.post("/api/v1/missions/check-envelope/", {"steps": steps}, format="json")
    assert check.json()["violations"] == []
    assert "terrain clearance is not checked" in check.json()["terrain_warnings"][0]["message"]


def test_a_void_under_a_leg_is_a_warning_of_the_plan_check(terrain_dir, tmp_path, hill, world):
    # South of home, away from the hill.
    import_path(write_hgt(tmp_path, with_void(hill, *ned_to_latlon(-300.0, 0.0, HOME))))
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 40}},
        {"command": "navigate", "params": {"lat": ned_to_latlon(0.0, -800.0, HOME)[0],
                                           "lon": ned_to_latlon(0.0, -800.0, HOME)[1]}},
        {"command": "navigate", "params": {"lat": ned_to_latlon(-600.0, 800.0, HOME)[0],
                                           "lon": ned_to_latlon(-600.0, 800.0, HOME)[1]}},
    ]  # fmt: skip
    check = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", {"steps": steps}, format="json"
    )
    assert check.json()["violations"] == []
    (warning,) = check.json()["terrain_warnings"]
    assert warning["step"] == 3 and "(void)" in warning["message"]
    assert [g["reason"] for g in warning["gaps"]] == ["void"]


# -- QGroundControl plans in terrain frame ------------------------------------------------------


def terrain_frame_plan() -> dict:
    south = ned_to_latlon(-400.0, 0.0, HOME)
    top = hill_tile().hill_top()

    def item(number: int, command: int, frame: int, mode: int, altitude: float, point, p6=None):  # type: ignore[no-untyped-def]
        return {
            "AMSLAltAboveTerrain": 999 if mode == 3 else None, "Altitude": altitude,
            "AltitudeMode": mode, "autoContinue": True, "command": command,
            "doJumpId": number, "frame": frame, "type": "SimpleItem",
            "params": [0, 0, 0, None, point[0], point[1], altitude if p6 is None else p6],
        }  # fmt: skip

    items = [
        item(1, 22, 10, 4, 300, HOME),  # take off to 300 m above the terrain at home
        # Over home at that height first: the leg to the hill top leaves once it is there
        # (its waypoint's wait_for_flight), not while still climbing out.
        item(2, 16, 10, 4, 300, HOME),
        item(3, 16, 10, 4, 80, top),  # 80 m above the hill top: MAV_FRAME_GLOBAL_TERRAIN_ALT
        item(4, 16, 0, 3, 100, south, p6=999),  # "calculated above terrain" (QGC's own AMSL)
        item(5, 21, 3, 1, 0, HOME),
    ]
    return {
        "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {"cruiseSpeed": 15, "firmwareType": 12, "hoverSpeed": 5, "items": items,
                    "plannedHomePosition": [*HOME, GROUND], "vehicleType": 2, "version": 2},
    }  # fmt: skip


def import_plan(world, plan: dict):  # type: ignore[no-untyped-def]
    upload = SimpleUploadedFile("terrain.plan", json.dumps(plan).encode())
    return client_for(world.operator).post(
        "/api/v1/missions/import-plan/",
        {"file": upload, "confirm_beyond_defaults": "true"},
        format="multipart",
    )


def test_a_terrain_frame_plan_imports_with_heights_above_home(hill_imported, high_envelope):
    response = import_plan(high_envelope, terrain_frame_plan())
    assert response.status_code == 201, response.json()
    mission = Mission.objects.get()
    altitudes, altitude = [], 0.0
    for step in mission.steps.order_by("index"):
        if step.command == "takeoff":
            altitude = step.params["altitude"]
            altitudes.append(altitude)
        elif step.command == "navigate" and "altitude_delta" in step.params:
            altitude += step.params["altitude_delta"]
            altitudes.append(altitude)
    dem = hill_imported
    home_ground = dem.bilinear(*HOME)
    south = ned_to_latlon(-400.0, 0.0, HOME)
    expected = [
        300.0,
        300.0,
        dem.bilinear(*dem.hill_top()) + 80.0 - home_ground,
        dem.bilinear(*south) + 100.0 - home_ground,
    ]
    expected.append(expected[-1])  # the landing item: back over home at that height
    assert altitudes == pytest.approx(expected, abs=1e-3)
    assert expected[2] == pytest.approx(280.0)


def test_a_terrain_frame_plan_without_terrain_is_refused_with_the_reason(
    terrain_dir, high_envelope
):
    plan = terrain_frame_plan()
    response = import_plan(high_envelope, plan)
    assert response.status_code == 400
    error = response.json()["error"]
    assert error.startswith("mission.items[0]: its altitude is above terrain, no imported")
    assert not Mission.objects.exists()

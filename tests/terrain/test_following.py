"""Terrain following: a coverage over the 200 m hill flown at a constant height above the
ground (within the tolerance everywhere along the path, checked against the DEM itself),
through the REST API; refused naming the field where there is no terrain to follow."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rest_framework.test import APIClient

from fleet import envelopes
from missions.models import Mission
from onboard.envelope import latlon_to_ne, ned_to_latlon
from terrain.following import follow
from terrain.importer import import_path

from .dem import HOME, Dem, write_hgt

pytestmark = pytest.mark.django_db
HEIGHT = 50.0
TOLERANCE = 10.0


def north(metres: float, east: float = 0.0) -> tuple[float, float]:
    return ned_to_latlon(metres, east, HOME)


# A strip 20 m wide from 100 m to 1000 m north of home, over the hill top (600 m north).
STRIP = [list(north(100)), list(north(1000)), list(north(1000, 20))]
WAYPOINTS = [north(100), north(400), north(700), north(1000)]


@pytest.fixture
def hill_imported(terrain_dir, tmp_path, hill) -> Dem:  # type: ignore[no-untyped-def]
    import_path(write_hgt(tmp_path, hill))
    return hill


@pytest.fixture
def high_envelope(world):  # type: ignore[no-untyped-def]
    envelopes.set_envelope(world.org, {"max_height": 400, "max_distance": 2000, "home": list(HOME)})
    return world


def heights_above_ground(dem: Dem, path: list[tuple[float, float, float]]) -> np.ndarray:
    """The height above the DEM's ground, every 5 m along straight legs between the path's
    (lat, lon, height above home) points."""
    home_ground = dem.bilinear(*HOME)
    found = []
    for (a_lat, a_lon, a_h), (b_lat, b_lon, b_h) in zip(path, path[1:], strict=False):
        n, e = latlon_to_ne(b_lat, b_lon, (a_lat, a_lon))
        for f in np.linspace(0.0, 1.0, max(2, math.ceil(math.hypot(n, e) / 5.0) + 1)):
            lat, lon = a_lat + (b_lat - a_lat) * f, a_lon + (b_lon - a_lon) * f
            found.append(a_h + (b_h - a_h) * f + home_ground - dem.bilinear(lat, lon))
    return np.array(found)


def test_the_path_keeps_its_height_above_the_hill_within_the_tolerance(hill_imported):
    points = follow(HOME, WAYPOINTS, HEIGHT, TOLERANCE)
    flat = [x for p in points if p.waypoint for x in (p.lat, p.lon)]
    assert flat == pytest.approx([x for w in WAYPOINTS for x in w])
    assert len(points) > len(WAYPOINTS), "no point was added over the hill"
    path = [(*HOME, HEIGHT)] + [(p.lat, p.lon, p.height) for p in points]
    agl = heights_above_ground(hill_imported, path)
    assert np.all(np.abs(agl - HEIGHT) <= TOLERANCE + 0.5), (agl.min(), agl.max())
    # Over the top the drone is ~250 m above home: the height followed the ground.
    assert max(p.height for p in points) > 200


def test_a_tighter_tolerance_adds_points_and_follows_closer(hill_imported):
    loose = follow(HOME, WAYPOINTS, HEIGHT, 20.0)
    tight = follow(HOME, WAYPOINTS, HEIGHT, 2.0)
    assert len(tight) > len(loose)
    path = [(*HOME, HEIGHT)] + [(p.lat, p.lon, p.height) for p in tight]
    agl = heights_above_ground(hill_imported, path)
    assert np.all(np.abs(agl - HEIGHT) <= 2.5), np.abs(agl - HEIGHT).max()


def coverage(**following) -> dict:
    return {
        "name": "terrain-following strip",
        "altitude": HEIGHT,
        "confirm_beyond_defaults": True,
        "coverage": {
            "vertices": STRIP,
            "step_distance": 300,
            "intermediate_action": "takepic",
            "terrain_following": {"home": list(HOME), "tolerance_m": TOLERANCE, **following},
        },
    }


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def flown_heights(mission: Mission) -> list[tuple[float, float, float, float | None]]:
    """(lat, lon, height above home, speed) at every navigate, accumulating deltas."""
    path, height = [], 0.0
    for step in mission.steps.order_by("index"):
        if step.command == "takeoff":
            height = step.params["altitude"]
        elif step.command == "navigate":
            height += step.params.get("altitude_delta", 0.0)
            path.append((step.params["lat"], step.params["lon"], height, step.params.get("speed")))
    return path


def test_a_terrain_following_survey_is_created_through_the_api(hill_imported, high_envelope):
    response = client_for(high_envelope.operator).post(
        "/api/v1/missions/", coverage(), format="json"
    )
    assert response.status_code == 201, response.json()
    mission = Mission.objects.get()
    assert mission.plan_home == pytest.approx(list(HOME))
    kept = mission.extensibility["terrain_following"]
    assert kept == {"home": list(HOME), "tolerance_m": TOLERANCE, "height_agl_m": HEIGHT}
    path = flown_heights(mission)
    agl = heights_above_ground(hill_imported, [(*HOME, HEIGHT)] + [p[:3] for p in path])
    assert np.all(np.abs(agl - HEIGHT) <= TOLERANCE + 0.5)
    # Photos only at the four coverage waypoints, not at the points added over the hill.
    assert mission.steps.filter(command="takepic").count() == 4
    # No leg climbs faster than 2 m/s nor descends faster than 1 m/s at its speed.
    last = (*HOME, HEIGHT)
    for lat, lon, height, speed in path:
        across = math.hypot(*latlon_to_ne(lat, lon, last[:2]))
        length, rise = math.hypot(across, height - last[2]), height - last[2]
        assert abs(rise) * speed / length <= (2.0 if rise > 0 else 1.0) + 1e-2
        last = (lat, lon, height)


def test_the_same_survey_flat_at_fifty_metres_hits_the_hill(hill_imported, high_envelope):
    flat = coverage()
    del flat["coverage"]["terrain_following"]
    response = client_for(high_envelope.operator).post("/api/v1/missions/", flat, format="json")
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "terrain_clearance"


def test_without_terrain_the_survey_is_refused_naming_the_field(terrain_dir, high_envelope):
    response = client_for(high_envelope.operator).post(
        "/api/v1/missions/", coverage(), format="json"
    )
    assert response.status_code == 400
    assert "coverage.terrain_following" in response.json()["fields"], response.json()
    assert "no terrain" in response.json()["error"]
    assert not Mission.objects.exists()


@pytest.mark.parametrize(
    ("following", "field"),
    [
        ({"tolerance_m": 0.2}, "coverage.terrain_following.tolerance_m"),
        ({"climb_m_s": -1}, "coverage.terrain_following.climb_m_s"),
        ({"home": "here"}, "coverage.terrain_following.home"),
    ],
)
def test_bad_following_parameters_are_refused(hill_imported, high_envelope, following, field):
    response = client_for(high_envelope.operator).post(
        "/api/v1/missions/", coverage(**following), format="json"
    )
    assert response.status_code == 400
    assert field in response.json()["fields"], response.json()
    assert not Mission.objects.exists()


def test_the_coverage_endpoint_answers_the_followed_path(hill_imported, high_envelope):
    body = {"vertices": STRIP, "step_distance": 300, "altitude": HEIGHT,
            "terrain_following": {"home": list(HOME), "tolerance_m": TOLERANCE}}  # fmt: skip
    response = client_for(high_envelope.viewer).post(
        "/api/v1/missions/coverage/", body, format="json"
    )
    assert response.status_code == 200, response.json()
    followed = response.json()["followed"]
    flat = [x for p in followed if p["waypoint"] for x in (p["lat"], p["lon"])]
    assert flat == pytest.approx([x for w in WAYPOINTS for x in w])
    path = [(*HOME, HEIGHT)] + [(p["lat"], p["lon"], p["height_m"]) for p in followed]
    agl = heights_above_ground(hill_imported, path)
    assert np.all(np.abs(agl - HEIGHT) <= TOLERANCE + 0.5)
    assert all(0.1 <= p["speed_m_s"] <= 5.0 for p in followed)


def test_a_drone_taking_off_from_other_ground_is_refused(hill_imported, high_envelope):
    from tests.missions.conftest import online_drone

    world = high_envelope
    client = client_for(world.operator)
    created = client.post("/api/v1/missions/", coverage(), format="json")
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    # On the hill's slope, ~100 m above the ground at the plan's home.
    online_drone(world.org, "ACME_SLOPE", north=400.0)
    refused = client.post(
        f"/api/v1/missions/{mission_id}/start/",
        {"drone": "ACME_SLOPE", "confirm_beyond_defaults": True},
        format="json",
    )
    assert refused.status_code == 409, refused.json()
    assert refused.json()["code"] == "terrain_clearance"
    assert "Plan the mission from this drone's home" in refused.json()["error"]
    assert Mission.objects.get(pk=mission_id).status == "draft"

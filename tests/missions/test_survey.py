"""Survey planning from a camera: spacings, height and estimates against values worked out
by hand from the photogrammetry relations, and the API that serves them."""

from __future__ import annotations

import math

import pytest
from rest_framework.test import APIClient

from missions import survey
from missions.planning import PlanningError

from .conftest import online_drone, point_at, rectangle

P4 = survey.PRESETS["DJI Phantom 4 Pro"]  # 13.2 × 8.8 mm sensor, 8.8 mm lens, 5472 px wide


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def test_height_gives_resolution_footprint_and_spacings():
    g = survey.geometry(P4, overlap=0.8, sidelap=0.7, height_m=100)
    # GSD = 100 m × 13.2 mm / (8.8 mm × 5472 px); footprint 150 m × 100 m.
    assert g.gsd_cm == pytest.approx(100 * 100 * 13.2 / (8.8 * 5472))
    assert g.footprint_width_m == pytest.approx(150.0)
    assert g.footprint_height_m == pytest.approx(100.0)
    assert g.line_spacing_m == pytest.approx(45.0)  # 150 × (1 − 0.7)
    assert g.photo_spacing_m == pytest.approx(20.0)  # 100 × (1 − 0.8)


def test_wanted_resolution_gives_the_height():
    g = survey.geometry(P4, overlap=0.75, sidelap=0.6, gsd_cm=2.0)
    assert g.height_m == pytest.approx(0.02 * 8.8 * 5472 / 13.2)  # 72.96 m
    assert g.gsd_cm == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"overlap": 0.99, "sidelap": 0.7, "height_m": 50}, "overlap"),
        ({"overlap": 0.8, "sidelap": -0.1, "height_m": 50}, "sidelap"),
        ({"overlap": 0.8, "sidelap": 0.7}, "height_m"),
        ({"overlap": 0.8, "sidelap": 0.7, "height_m": 50, "gsd_cm": 2}, "height_m"),
        ({"overlap": 0.8, "sidelap": 0.7, "height_m": 5000}, "height_m"),
        ({"overlap": 0.8, "sidelap": 0.7, "gsd_cm": float("nan")}, "gsd_cm"),
    ],
)
def test_impossible_surveys_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(PlanningError) as caught:
        survey.geometry(P4, **kwargs)
    assert caught.value.field == field


def test_a_custom_camera_needs_every_size():
    with pytest.raises(PlanningError, match="camera.focal_length_mm"):
        survey.camera_from(
            {
                "sensor_width_mm": 6,
                "sensor_height_mm": 4,
                "image_width_px": 4000,
                "image_height_px": 3000,
            }
        )
    with pytest.raises(PlanningError, match="unknown camera"):
        survey.camera_from("Hasselblad 500C")


def test_the_gear_camera_names_its_preset():
    assert survey.preset_for(" gopro hero3 ") == "GoPro Hero3"
    assert survey.preset_for("Unknown cam") is None


def test_estimate_of_a_serpentine_from_home():
    # Three lines of 100 m, 45 m apart, photos every 20 m: 6 × 3 waypoints; home at A.
    home = list(point_at(0, 0))
    waypoints = [point_at(row * 45, col * 20) for row in range(3) for col in range(6)]
    e = survey.estimate(waypoints, home=home, height_m=100, speed_m_s=5, endurance_s=1200)
    # Legs: 0 to the first waypoint, 300 m along the lines (row order here, not serpentine:
    # every line starts at the west edge), two returns across, and back from (90, 100) home.
    grid = [(r * 45, c * 20) for r in range(3) for c in range(6)]
    route = [(0, 0), *grid, (0, 0)]
    legs = [math.dist(a, b) for a, b in zip(route, route[1:], strict=False)]
    assert e.distance_m == pytest.approx(sum(legs), rel=2e-3)
    seconds = (
        sum(legs) / 5
        + 18 * survey.STOP_OVERHEAD_S
        + 100 / survey.CLIMB_M_S
        + 100 / survey.DESCENT_M_S
    )
    assert e.flight_time_s == pytest.approx(seconds, rel=2e-3)
    assert e.waypoints == e.photos == 18
    assert e.battery_pct == pytest.approx(100 * seconds / 1200, rel=2e-3)


def test_survey_api_plans_lines_photos_and_estimates(world):
    body = {
        "vertices": rectangle(100, 90),  # A→B 100 m east, B→C 90 m north
        "camera": "DJI Phantom 4 Pro",
        "overlap": 0.8,
        "sidelap": 0.7,
        "height_m": 100,
        "speed_m_s": 5,
    }
    response = client_for(world.operator).post("/api/v1/missions/survey/", body, format="json")
    assert response.status_code == 200, response.json()
    data = response.json()
    assert data["geometry"]["line_spacing_m"] == pytest.approx(45.0)
    assert data["coverage"]["step_distance"] == pytest.approx(20.0)
    assert len(data["coverage"]["waypoints"]) == 6 * 3
    # Serpentine 3 × 100 m + 2 × 45 m, then back from the far corner (100 m, 90 m) to A.
    distance = 3 * 100 + 2 * 45 + math.hypot(100, 90)
    assert data["total"]["distance_m"] == pytest.approx(distance, rel=2e-3)
    assert data["total"]["photos"] == 18
    assert data["drones"] == []


def test_survey_api_splits_the_estimate_between_drones(world):
    org = world.org
    online_drone(org, "ACME_A", north=0, east=0, battery=0.9)
    online_drone(org, "ACME_B", north=90, east=100, battery=0.35)
    body = {
        "vertices": rectangle(100, 90),
        "camera": "DJI Phantom 4 Pro",
        "overlap": 0.8,
        "sidelap": 0.7,
        "height_m": 100,
        "drones": ["ACME_A", "ACME_B"],
    }
    response = client_for(world.operator).post("/api/v1/missions/survey/", body, format="json")
    assert response.status_code == 200, response.json()
    shares = {d["drone"]: d for d in response.json()["drones"]}
    assert shares["ACME_A"]["waypoints"] + shares["ACME_B"]["waypoints"] == 18
    assert shares["ACME_A"]["battery_now_pct"] == pytest.approx(90.0)
    for share in shares.values():
        # 20 minutes on a full battery unless the gear says otherwise.
        assert share["battery_pct"] == pytest.approx(100 * share["flight_time_s"] / 1200, abs=0.06)
        end = share["battery_now_pct"] - share["battery_pct"]
        assert share["battery_at_end_pct"] == pytest.approx(end, abs=0.11)
        assert share["enough"] is (end >= 30.0)
    assert shares["ACME_B"]["enough"] is False  # 35 % now, 30 % reserve


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"camera": "Nope"}, "camera"),
        ({"overlap": 1.5}, "overlap"),
        ({"vertices": [[0, 0]]}, "vertices"),
        ({"drones": ["GLOBEX_1"]}, "drones"),
        ({"speed_m_s": 0}, "speed_m_s"),
    ],
)
def test_survey_api_refuses_bad_input_naming_the_field(world, change, field):
    body = {
        "vertices": rectangle(100, 90),
        "camera": "DJI Phantom 4 Pro",
        "overlap": 0.8,
        "sidelap": 0.7,
        "height_m": 100,
        **change,
    }
    response = client_for(world.operator).post("/api/v1/missions/survey/", body, format="json")
    assert response.status_code == 400
    assert field in str(response.json())


def test_cameras_lists_presets_and_what_each_drone_carries(world):
    world.drone.sensors = {"CAMERA": "GoPro Hero3"}
    world.drone.save()
    response = client_for(world.viewer).get("/api/v1/missions/survey/cameras/")
    assert response.status_code == 200
    data = response.json()
    assert "DJI Phantom 4 Pro" in [c["name"] for c in data["presets"]]
    assert data["drones"] == {"ACME_1": "GoPro Hero3"}
    assert APIClient().get("/api/v1/missions/survey/cameras/").status_code in (401, 403)

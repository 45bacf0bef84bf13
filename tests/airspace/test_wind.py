"""The wind rule with the whole ground: simulated PX4 and ArduPilot drones (the software
flight controller reporting its wind, the real onboard agent, a real broker, gateway and
Celery worker). Above the gear's limit a take-off and a mission start are refused with
409 `wind` and the figure; a wind raised above it in flight makes the drone return and
raises a WARNING alert; below it the mission is flown."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from django.test import Client

from alerts.models import Alert
from firmware.sim.wind import write_wind
from fleet.models import Drone
from missions.models import Event, MissionStatus
from tests.airspace.test_e2e import start as start_mission
from tests.missions.conftest import point_at
from tests.missions.sky import Sky
from tests.support.experiments import api, ground, wait_status  # noqa: F401
from tests.support.ground import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

LIMIT = 8.0
BOTH = pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = Sky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


def windy_drone(sky: Sky, drone_id: str, autopilot: str, speed: float) -> Path:
    """A drone whose gear limits the wind to LIMIT, in `speed` m/s from the west; the wind
    file it returns changes the wind."""
    folder = sky.tmp_path / drone_id
    (folder / "gear").mkdir(parents=True)
    specs = {"TYPE": "QUADCOPTER", "MAX_WIND_M_S": LIMIT}
    (folder / "gear" / "specs.json").write_text(json.dumps(specs))
    wind_file = folder / "wind"
    write_wind(wind_file, speed, 270.0)
    sky.add_drone(
        drone_id,
        fc="mavlink",
        extra=["--wind-hold", "3"],
        extra_args=["--autopilot", autopilot, "--wind-file", str(wind_file)],
    )
    sky.wait_online()
    assert wait_for(lambda: wind_of(drone_id) and specs_of(drone_id), 20), sky.describe()
    return wind_file


def wind_of(drone_id: str) -> dict | None:
    return (Drone.objects.get(drone_id=drone_id).fc or {}).get("wind")


def specs_of(drone_id: str) -> dict:
    return Drone.objects.get(drone_id=drone_id).specs


def events_of(mission_id: str) -> list[str]:
    return list(Event.objects.filter(mission_id=mission_id).values_list("message", flat=True))


def stopped_for_wind(mission_id: str) -> bool:
    return any(
        "mission stopped (wind" in m and "limit of 8 m/s" in m for m in events_of(mission_id)
    )


def out_and_back(north: float) -> dict:
    there = point_at(north, 0.0)
    return {
        "name": f"{north:g} m north and back",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 10}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": there[0], "lon": there[1]}},
            {"command": "wait_for_flight"},
            {"command": "sleep", "params": {"value": 60}},
            {"command": "land"},
        ],
    }


@BOTH
def test_take_off_and_mission_start_above_the_limit_are_refused_with_the_figure(
    world_tx, sky, autopilot
):
    windy_drone(sky, "ACME_W1", autopilot, 12.0)
    client = api(world_tx.operator)
    for command, params in (("arm", {}), ("takeoff", {"altitude": 10})):
        refused = client.post(
            "/api/v1/drones/ACME_W1/commands/",
            {"command": command, "params": params},
            format="json",
        )
        assert refused.status_code == 409, refused.json()
        assert refused.json()["code"] == "wind"
        assert "Wind 12.0 m/s" in refused.json()["error"]
        assert "limit of 8 m/s" in refused.json()["error"]
    _, started = start_mission(world_tx, out_and_back(20), "ACME_W1")
    assert started.status_code == 409 and started.json()["code"] == "wind", started.json()
    assert "Wind 12.0 m/s" in started.json()["error"]
    drone = Drone.objects.get(drone_id="ACME_W1")
    assert not drone.armed and not drone.airborne
    # The drone page shows the wind against the limit.
    browser = Client()
    browser.force_login(world_tx.operator)
    page = browser.get("/drones/ACME_W1/")
    assert page.status_code == 200
    html = page.content.decode()
    assert "12.0 m/s from 270°" in html and "above the limit: take-off refused" in html


@BOTH
def test_wind_raised_above_the_limit_in_flight_returns_the_drone_and_warns(
    world_tx, sky, autopilot
):
    wind_file = windy_drone(sky, "ACME_W2", autopilot, 4.0)
    mission_id, started = start_mission(world_tx, out_and_back(40), "ACME_W2")
    assert started.status_code == 200, started.json()
    assert wait_for(
        lambda: (d := Drone.objects.get(drone_id="ACME_W2")).airborne and d.alt > 9, 30
    ), sky.describe()
    write_wind(wind_file, 12.0, 270.0)
    alert = wait_for(lambda: Alert.objects.filter(kind="wind", drone_id="ACME_W2").first(), 30)
    assert alert is not None, wind_of("ACME_W2")
    assert alert.severity == Alert.Severity.WARNING
    assert "returns home" in alert.title and "limit of 8 m/s" in alert.title
    # The drone stopped its mission saying why (the ground then decides what follows).
    assert wait_for(lambda: stopped_for_wind(mission_id), 20), events_of(mission_id)
    home = point_at(0.0, 0.0)

    def landed_home() -> bool:
        d = Drone.objects.get(drone_id="ACME_W2")
        near = abs(d.lat - home[0]) < 5e-5 and abs(d.lon - home[1]) < 5e-5
        return near and not d.armed and (d.alt or 0.0) < 0.5

    assert wait_for(landed_home, 40), sky.describe()
    assert Alert.objects.filter(kind="wind", drone_id="ACME_W2").count() == 1


def test_below_the_limit_the_mission_is_flown(world_tx, sky):
    windy_drone(sky, "ACME_W3", "px4", 6.0)
    mission = out_and_back(20)
    mission["steps"][5] = {"command": "sleep", "params": {"value": 2}}
    mission_id, started = start_mission(world_tx, mission, "ACME_W3")
    assert started.status_code == 200, started.json()
    assert wait_status(mission_id, {"completed", "failed", "stopped"}, 60).status == (
        MissionStatus.COMPLETED
    )
    assert not Alert.objects.filter(kind="wind").exists()

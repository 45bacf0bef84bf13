"""The whole ground with a simulated MAVLink drone (simulator + real agent): the serial
number its battery reports in SMART_BATTERY_INFO reaches the ground in the heartbeat and
attaches the pack to the drone; once the pack is retired, an arm through the commands
API answers 409 not_airworthy naming it."""

from __future__ import annotations

import pytest

from batteries.models import Battery
from fleet.models import Drone
from runtime.processes import wait_for
from tests.fleet.conftest import (  # noqa: F401 (fixtures)
    _shared_broker,
    broker,
    client_for,
    drone_url,
    fresh_redis,
    gateway,
)
from tests.support.mavlink_drone import simulated_mavlink_drone

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_BAT1"
SERIAL = "SIMPACK-0001"


@pytest.fixture(params=["ardupilot", "px4"])
def smart_battery_drone(request, world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]  # noqa: F811
    """ACME_BAT1 on a simulated autopilot whose battery reports serial SIMPACK-0001."""
    settings.HEARTBEAT_INTERVAL_S = 0.5
    Drone.objects.create(organisation=world_tx.org, drone_id=DRONE)
    with simulated_mavlink_drone(
        DRONE,
        drone_url(broker, DRONE),
        tmp_path,
        ["--autopilot", request.param, "--battery-serial", SERIAL],
    ):
        yield


def reported() -> str | None:
    return (Drone.objects.get(drone_id=DRONE).fc or {}).get("battery_serial")


def test_the_reported_serial_attaches_the_battery(world_tx, smart_battery_drone):
    assert wait_for(lambda: reported() == SERIAL, timeout=30, interval=0.1), reported()
    client = client_for(world_tx.operator)
    carried = client.get(f"/api/v1/drones/{DRONE}/battery/").json()
    assert carried["reported_serial"] == SERIAL
    assert carried["battery"]["serial"] == SERIAL and carried["battery"]["reported"] is True
    assert carried["battery"]["drone"] == DRONE
    # Rated from the drone's gear specs: 5500 mAh, 4 cells of 3.7 V.
    assert carried["battery"]["rated_energy_wh"] == pytest.approx(81.4)
    listed = client.get("/api/v1/batteries/").json()["results"]
    assert [(b["serial"], b["drone"]) for b in listed] == [(SERIAL, DRONE)]
    # A member cannot put another pack on a drone whose flight controller names its own.
    refused = client.put(
        f"/api/v1/drones/{DRONE}/battery/", {"battery": None}, content_type="application/json"
    )
    assert refused.status_code == 400 and SERIAL in refused.json()["fields"]["battery"][0]

    # The pack has flown 350 cycles; a limit of 300 retires it, and the drone cannot arm.
    Battery.objects.filter(serial=SERIAL).update(cycles=350.0)
    admin = client_for(world_tx.owner)
    rules = admin.put(
        f"/api/v1/organisations/{world_tx.org.slug}/battery-policy/",
        {"cycle_limit": 300},
        content_type="application/json",
    )
    assert rules.status_code == 200, rules.content
    response = client.post(
        f"/api/v1/drones/{DRONE}/commands/",
        {"command": "arm", "params": {}},
        content_type="application/json",
    )
    assert response.status_code == 409, response.content
    assert response.json()["code"] == "not_airworthy"
    assert (
        f"battery {SERIAL} retired: 350.0 cycles above the limit of 300"
        in (response.json()["error"])
    )
    assert not Drone.objects.get(drone_id=DRONE).armed

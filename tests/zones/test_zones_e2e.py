"""End to end: a simulated drone (simulator + the real onboard agent) flown through the
commands API around a published zone — refused inside the zone's band before anything
is sent, flown over it above the band."""

from __future__ import annotations

import json

import pytest

from fleet.models import Drone
from onboard import envelope as env
from runtime.processes import wait_for
from tests.fleet.conftest import client_for
from tests.fleet.test_e2e import HEARTBEAT_S, start_fleet
from zones.store import import_bytes

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_SIM1"


def field_around(home: tuple[float, float]) -> bytes:
    """A GeoJSON zone 100–200 m north of home, ±50 m east, prohibited from 0 to 60 m AGL."""
    corners = [(100, -50), (100, 50), (200, 50), (200, -50), (100, -50)]
    ring = [list(reversed(env.ned_to_latlon(n, e, home))) for n, e in corners]
    band = {
        "lowerLimit": 0,
        "upperLimit": 60,
        "uomDimensions": "M",
        "lowerVerticalReference": "AGL",
        "upperVerticalReference": "AGL",
    }
    feature = {
        "type": "Feature",
        "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {"identifier": "E2E-1", "name": "Field", "restriction": "PROHIBITED", **band},
    }
    return json.dumps({"type": "FeatureCollection", "features": [feature]}).encode()


@pytest.fixture
def drone(world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]
    settings.HEARTBEAT_INTERVAL_S = HEARTBEAT_S
    running = start_fleet(tmp_path, broker.port, ids=(DRONE,))
    try:
        assert wait_for(
            lambda: Drone.objects.filter(drone_id=DRONE, online=True, lat__isnull=False).exists(),
            timeout=30,
            interval=0.1,
        ), "the simulated drone came online with a position"
        yield Drone.objects.get(drone_id=DRONE)
    finally:
        running.stop()


def send(client, command: str, **params: object):  # type: ignore[no-untyped-def]
    return client.post(
        f"/api/v1/drones/{DRONE}/commands/",
        {"command": command, "params": params},
        content_type="application/json",
    )


def height(value: float) -> bool:
    drone = Drone.objects.get(drone_id=DRONE)
    return drone.alt is not None and abs(drone.alt - value) < 1.5


def test_a_real_drone_is_kept_out_of_the_band_and_flies_over_it(world_tx, drone):
    home = (drone.lat, drone.lon)
    import_bytes("field.geojson", field_around(home))
    client = client_for(world_tx.operator)
    assert send(client, "arm").json()["ok"] is True
    assert send(client, "takeoff", altitude=40).json()["ok"] is True
    assert wait_for(lambda: height(40.0), timeout=60, interval=0.2)

    inside = env.ned_to_latlon(150.0, 0.0, home)
    refused = send(client, "navigate", lat=inside[0], lon=inside[1])
    assert refused.status_code == 409 and refused.json()["code"] == "zone", refused.json()
    assert "'Field' (E2E-1, prohibited, 0 m AGL – 60 m AGL" in refused.json()["error"]

    assert send(client, "altitude", value=60).json()["ok"] is True
    assert wait_for(lambda: height(100.0), timeout=60, interval=0.2)
    flown = send(client, "navigate", lat=inside[0], lon=inside[1])
    assert flown.status_code == 200 and flown.json()["ok"] is True, flown.json()

    def over_the_field() -> bool:
        d = Drone.objects.get(drone_id=DRONE)
        north, east = env.latlon_to_ne(d.lat, d.lon, home)
        return 110 < north < 190 and abs(east) < 40 and d.alt > 90

    assert wait_for(over_the_field, timeout=90, interval=0.2)

"""Drones that are not airworthy are never chosen (replacement, collaboration, panic and a
mission's start share missions/selection.py), and an airborne drone whose heartbeat says
its Remote ID fails raises one WARNING alert per window."""

from __future__ import annotations

import time

import pytest
from rest_framework.test import APIClient

from alerts.models import Alert
from fleet.heartbeats import handle_heartbeats
from missions.selection import nearest_available
from onboard import protocol
from tests.missions.conftest import online_drone, outbox, point_at  # noqa: F401 (fixture)

FAILING = {"protocol": "mavlink", "remote_id": {"ok": False, "error": "no operator ID"}}


def test_selection_skips_a_drone_that_is_not_airworthy(world):
    near = online_drone(world.org, "ACME_NEAR", north=5)
    online_drone(world.org, "ACME_FAR", north=200)
    target = point_at(0, 0)
    assert [d.drone_id for d in nearest_available(world.org.pk, target=target)] == ["ACME_NEAR"]
    near.fc = FAILING
    near.save()
    chosen = nearest_available(world.org.pk, target=target, count=3)
    assert [d.drone_id for d in chosen] == ["ACME_FAR"]


def test_where_remote_id_is_required_a_drone_without_identity_is_skipped(world):
    world.org.require_remote_id = True
    world.org.operator_id = "FIN87astrdge12k8"
    world.org.save()
    online_drone(world.org, "ACME_NEAR", north=5)
    far = online_drone(world.org, "ACME_FAR", north=200)
    assert nearest_available(world.org.pk, target=point_at(0, 0)) == []
    far.serial_number = "MFR1C123456789ABC"
    far.remote_id_external = True  # a broadcast module of its own, declared by an admin
    far.save()
    assert [d.drone_id for d in nearest_available(world.org.pk, target=point_at(0, 0))] == [
        "ACME_FAR"
    ]


def test_a_chosen_drone_that_is_not_airworthy_cannot_start_a_mission(world, outbox):  # noqa: F811
    drone = online_drone(world.org, "ACME_1")
    drone.fc = FAILING
    drone.save()
    client = APIClient()
    client.force_authenticate(world.operator)
    lat, lon = point_at(20, 0)
    body = {
        "name": "survey",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 10}},
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "land"},
        ],
    }
    mission_id = client.post("/api/v1/missions/", body, format="json").json()["id"]
    response = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_1"}, format="json"
    )
    assert response.status_code == 409
    assert response.json()["code"] == "not_airworthy"
    assert "Remote ID failing: no operator ID" in response.json()["error"]
    assert outbox.items() == []


def heartbeat(drone_id: str, *, airborne: bool, ok: bool) -> protocol.Heartbeat:
    return protocol.Heartbeat(
        drone_id=drone_id,
        ts=time.time(),
        position=protocol.Position(40.63, -8.65, 12.0 if airborne else 0.0),
        battery_voltage=16.0,
        battery_remaining=0.8,
        armed=airborne,
        airborne=airborne,
        flight_mode="GUIDED",
        mission=None,
        fc_protocol="mavlink",
        fc_connected=True,
        remote_id=protocol.RemoteIdHealth(ok=ok, error="" if ok else "transmitter fault"),
    )


@pytest.mark.django_db(transaction=True)
def test_an_airborne_drone_with_failing_remote_id_raises_one_warning(world_tx, settings):
    settings.REMOTE_ID_ALERT_EVERY_S = 3600
    handle_heartbeats([("ACME_1", heartbeat("ACME_1", airborne=False, ok=False))])
    assert not Alert.objects.exists()  # on the ground the arm refusal is enough
    for _ in range(3):
        handle_heartbeats([("ACME_1", heartbeat("ACME_1", airborne=True, ok=False))])
    alert = Alert.objects.get()
    assert alert.kind == Alert.Kind.REMOTE_ID and alert.severity == Alert.Severity.WARNING
    assert alert.drone_id == "ACME_1" and "transmitter fault" in alert.title
    handle_heartbeats([("ACME_1", heartbeat("ACME_1", airborne=True, ok=True))])
    assert Alert.objects.count() == 1

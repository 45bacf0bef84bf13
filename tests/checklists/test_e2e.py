"""The whole ground with a simulated MAVLink drone (simulator + real agent over a real
link): its arm is refused with 409 checklist_required until an operator runs a checklist
whose automatic items the drone's own heartbeats pass; then it arms."""

from __future__ import annotations

import pytest

from checklists import definitions
from checklists.models import Policy
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

DRONE = "ACME_CK1"
ITEMS = [
    {"kind": "manual", "text": "Take-off area clear"},
    {"kind": "auto", "check": "battery", "threshold": 0.5},
    {"kind": "auto", "check": "link", "threshold": 5},
    {"kind": "auto", "check": "envelope"},
    {"kind": "auto", "check": "airworthy"},
]


@pytest.fixture
def drone(world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]  # noqa: F811
    settings.HEARTBEAT_INTERVAL_S = 0.5
    Policy.objects.create(organisation=world_tx.org, required=True, valid_minutes=30)
    template = definitions.create_template(
        world_tx.org, {"name": "Before flight", "items": ITEMS}, world_tx.owner
    )
    Drone.objects.create(organisation=world_tx.org, drone_id=DRONE)
    with simulated_mavlink_drone(DRONE, drone_url(broker, DRONE), tmp_path):
        yield template


def arm(client):  # type: ignore[no-untyped-def]
    body = {"command": "arm", "params": {}}
    return client.post(f"/api/v1/drones/{DRONE}/commands/", body, content_type="application/json")


def test_a_simulated_drone_arms_only_after_a_passed_checklist(world_tx, drone):
    def ready() -> bool:
        found = Drone.objects.get(drone_id=DRONE)
        return bool(
            found.online
            and found.battery_remaining
            and found.lat
            and (found.fc or {}).get("connected")
        )

    assert wait_for(ready, timeout=30, interval=0.1)
    client = client_for(world_tx.operator)
    refused = arm(client)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "checklist_required"
    assert not Drone.objects.get(drone_id=DRONE).armed

    body = {"template": drone.pk, "answers": [True]}
    run = client.post(f"/api/v1/drones/{DRONE}/checklists/", body, content_type="application/json")
    assert run.status_code == 201 and run.json()["passed"], run.json()
    link = run.json()["results"][2]
    assert link["value"]["fc_connected"] and link["value"]["heartbeat_age_s"] <= 5

    armed = arm(client)
    assert armed.status_code == 200, armed.content
    assert wait_for(lambda: Drone.objects.get(drone_id=DRONE).armed, timeout=20, interval=0.1)

"""The whole ground with a simulated MAVLink drone (simulator + real agent): a drone whose
maintenance is overdue is refused an arm with 409 not_airworthy naming the task; once an
admin signs the task off, the same arm reaches the drone and it arms."""

from __future__ import annotations

import pytest

from fleet.models import Drone
from maintenance.models import Schedule
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

from .support import flown

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_MNT1"


@pytest.fixture
def overdue_drone(world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]  # noqa: F811
    """ACME_MNT1 flying, with its 1-flight inspection owed after one recorded flight."""
    settings.HEARTBEAT_INTERVAL_S = 0.5
    drone = Drone.objects.create(organisation=world_tx.org, drone_id=DRONE)
    flown(drone, minutes=12)
    schedule = Schedule.objects.create(
        organisation=world_tx.org, drone=drone, name="Post-flight inspection", every_flights=1
    )
    with simulated_mavlink_drone(DRONE, drone_url(broker, DRONE), tmp_path):
        yield schedule


def _arm(user):  # type: ignore[no-untyped-def]
    return client_for(user).post(
        f"/api/v1/drones/{DRONE}/commands/",
        {"command": "arm", "params": {}},
        content_type="application/json",
    )


def test_an_overdue_drone_arms_only_after_the_sign_off(world_tx, overdue_drone):
    ready = Drone.objects.filter(drone_id=DRONE, online=True, lat__isnull=False)
    assert wait_for(ready.exists, timeout=30, interval=0.1)
    refused = _arm(world_tx.operator)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "not_airworthy"
    assert "'Post-flight inspection' due now at 1 flight" in refused.json()["error"]

    signed = client_for(world_tx.owner).post(
        f"/api/v1/drones/{DRONE}/maintenance/log/",
        {"schedule": overdue_drone.pk, "notes": "airframe inspected"},
        content_type="application/json",
    )
    assert signed.status_code == 201, signed.content
    armed = _arm(world_tx.operator)
    assert armed.status_code == 200, armed.content
    assert wait_for(lambda: Drone.objects.get(drone_id=DRONE).armed, timeout=20, interval=0.1)

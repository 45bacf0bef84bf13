"""The whole ground with a simulated MAVLink drone (simulator + real agent): the serial
number an admin sets reaches the drone's Remote ID module, and a module that fails makes
the drone not airworthy, so an arm through the commands API answers 409 not_airworthy."""

from __future__ import annotations

import pytest

from fleet.models import Drone, Organisation
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

from .test_agent_odid import received

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_RID1"
SERIAL = "MFR1C123456789ABC"


@pytest.fixture
def failing_drone(world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]  # noqa: F811
    """ACME_RID1: serial set, organisation registered, its Remote ID module failing."""
    settings.HEARTBEAT_INTERVAL_S = 0.5
    Organisation.objects.filter(pk=world_tx.org.pk).update(
        require_remote_id=True, operator_id="FIN87astrdge12k8"
    )
    Drone.objects.create(organisation=world_tx.org, drone_id=DRONE, serial_number=SERIAL)
    with simulated_mavlink_drone(
        DRONE, drone_url(broker, DRONE), tmp_path, ["--remote-id-fail", "transmitter fault"]
    ):
        yield


def remote_id_of() -> dict | None:
    return (Drone.objects.get(drone_id=DRONE).fc or {}).get("remote_id")


def test_a_failing_remote_id_keeps_the_drone_from_arming(world_tx, failing_drone, tmp_path):
    assert wait_for(lambda: remote_id_of() is not None, timeout=30, interval=0.1)
    assert remote_id_of() == {"ok": False, "error": "transmitter fault", "source": "odid"}
    # The ground sent the identity with the envelope when the drone came online.
    assert wait_for(
        lambda: (received(tmp_path, "OPEN_DRONE_ID_BASIC_ID") or {}).get("uas_id") == SERIAL,
        timeout=20,
        interval=0.1,
    )
    # The module records each message as it comes: the operator id follows the basic id.
    assert wait_for(
        lambda: (
            (received(tmp_path, "OPEN_DRONE_ID_OPERATOR_ID") or {}).get("operator_id")
            == "FIN87astrdge12k8"
        ),
        timeout=20,
        interval=0.1,
    )

    client = client_for(world_tx.operator)
    verdict = client.get(f"/api/v1/drones/{DRONE}/airworthiness/").json()
    assert verdict == {"airworthy": False, "reasons": ["Remote ID failing: transmitter fault"]}
    response = client.post(
        f"/api/v1/drones/{DRONE}/commands/",
        {"command": "arm", "params": {}},
        content_type="application/json",
    )
    assert response.status_code == 409, response.content
    assert response.json()["code"] == "not_airworthy"
    assert "transmitter fault" in response.json()["error"]
    assert not Drone.objects.get(drone_id=DRONE).armed

"""The simulator's Remote ID module, sans-I/O: it takes the Open Drone ID messages as the
agent encodes them, answers OPEN_DRONE_ID_ARM_STATUS, fails when the static messages stop
and then keeps the autopilot from arming, as ArduPilot does."""

from __future__ import annotations

import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim.remote_id import RemoteIdModule
from onboard.fc import odid
from onboard.protocol import RemoteIdentity
from tests.firmware.sim.test_mavlink_autopilots import Ground

IDENTITY = RemoteIdentity("MFR1C123456789ABC", "FIN87astrdge12k8", 2, "Survey", (40.63, -8.65))


def with_module(**kwargs) -> Ground:  # type: ignore[no-untyped-def]
    ground = Ground("ardupilot")
    ground.session.remote_id = RemoteIdModule(**kwargs)
    ground.session._default_streams()
    return ground


def send_identity(ground: Ground) -> None:
    for name, fields in odid.messages(
        IDENTITY, IDENTITY.operator_location, location_type=2, now=time.time()
    ):
        ground.send(name, 1, 0, *fields)


def run(ground: Ground, seconds: int) -> None:
    """Let time pass with the ground station's heartbeat each second (the autopilot
    streams only to a ground station it hears)."""
    for _ in range(seconds * 2):
        ground.send("heartbeat", mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        ground.run(0.5)


def arm_statuses(ground: Ground) -> list[tuple[int, str]]:
    return [(m.status, m.error) for m in ground.inbox if m.get_type() == "OPEN_DRONE_ID_ARM_STATUS"]


def test_the_module_records_the_identity_and_is_good_to_arm():
    ground = with_module()
    send_identity(ground)
    run(ground, 2)
    assert arm_statuses(ground)[-1] == (0, "")
    received = ground.session.remote_id.received
    assert received["OPEN_DRONE_ID_BASIC_ID"]["uas_id"] == "MFR1C123456789ABC"
    assert received["OPEN_DRONE_ID_OPERATOR_ID"]["operator_id"] == "FIN87astrdge12k8"
    assert received["OPEN_DRONE_ID_SYSTEM"]["operator_latitude"] == 406300000
    assert ground.arm() == mavlink.MAV_RESULT_ACCEPTED


def test_without_basic_id_for_five_seconds_it_fails_and_arming_is_denied():
    ground = with_module()
    send_identity(ground)
    run(ground, 7)
    status, error = arm_statuses(ground)[-1]
    assert status == 1 and error.startswith("no Basic ID for")
    assert ground.arm() == mavlink.MAV_RESULT_DENIED
    assert any(t.startswith("PreArm: OpenDroneID: no Basic ID") for t in ground.texts())
    send_identity(ground)
    run(ground, 2)
    assert arm_statuses(ground)[-1] == (0, "")


def test_a_module_told_to_fail_fails_whatever_it_gets():
    ground = with_module(fail_reason="transmitter fault")
    send_identity(ground)
    run(ground, 2)
    assert arm_statuses(ground)[-1] == (1, "transmitter fault")

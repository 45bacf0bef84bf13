"""The heartbeat's optional battery.serial on the wire, and the simulator's and the
MAVLink driver's SMART_BATTERY_INFO, encoded and decoded by the MAVLink codec."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim.mavlink_server import MavlinkSession
from firmware.sim.vehicle import Vehicle
from onboard import protocol
from onboard.fc.mavlink import MavlinkCodec, battery_serial


def _beat(**changes) -> dict:  # type: ignore[no-untyped-def]
    beat = protocol.Heartbeat(
        "ACME_1", 1.0, None, 16.2, 0.9, False, False, "LOITER", None, "mavlink", True, **changes
    )
    return beat.to_dict()


def test_the_serial_is_optional_and_round_trips():
    assert "serial" not in _beat()["battery"]
    assert protocol.parse_heartbeat(_beat()).battery_serial is None
    wire = _beat(battery_serial="PK-0042")
    assert wire["battery"] == {"voltage": 16.2, "remaining": 0.9, "serial": "PK-0042"}
    assert protocol.parse_heartbeat(wire).battery_serial == "PK-0042"


@pytest.mark.parametrize("serial", [42, "", "x" * 33, "bad\x00serial"])
def test_a_bad_serial_is_refused_naming_the_field(serial):
    wire = _beat()
    wire["battery"]["serial"] = serial
    with pytest.raises(protocol.ProtocolError) as refused:
        protocol.parse_heartbeat(wire)
    assert refused.value.field == "battery.serial"


def test_the_simulated_pack_answers_request_message_with_its_serial():
    session = MavlinkSession(vehicle=Vehicle(), battery_serial="SIMPACK-7")
    ground = MavlinkCodec(255, mavlink.MAV_COMP_ID_MISSIONPLANNER)
    request = ground.encode(
        "command_long", 1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
        mavlink.MAVLINK_MSG_ID_SMART_BATTERY_INFO, 0, 0, 0, 0, 0, 0,
    )  # fmt: skip
    session.receive(request, 0.0)
    answers = {m.get_type(): m for m in ground.feed(session.take_output())}
    assert answers["COMMAND_ACK"].result == mavlink.MAV_RESULT_ACCEPTED
    info = answers["SMART_BATTERY_INFO"]
    assert battery_serial(info) == "SIMPACK-7"
    assert info.capacity_full_specification == 5500 and info.cells_in_series == 4
    # Without a serial the simulated pack sends nothing.
    silent = MavlinkSession(vehicle=Vehicle())
    silent.receive(request, 0.0)
    assert "SMART_BATTERY_INFO" not in {m.get_type() for m in ground.feed(silent.take_output())}

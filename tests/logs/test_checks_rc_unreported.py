"""A telemetry log whose vehicle never reports an RC receiver present (SYS_STATUS without
MAV_SYS_STATUS_SENSOR_RC_RECEIVER, as a drone flown only by its companion computer)
tells nothing of RC loss: not checked, never a pass. Written with pymavlink, the
tlog's own structure (an 8-byte big-endian µs stamp before each packet)."""

from __future__ import annotations

import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from logs.checks import run_checks
from logs.store import import_to_store

T0_US = 1_700_000_000_000_000
GPS_BIT = mavlink2.MAV_SYS_STATUS_SENSOR_GPS


def _tlog(path, rc_bit: int):  # type: ignore[no-untyped-def]
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    armed = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    sensors = GPS_BIT | rc_bit
    with open(path, "wb") as f:
        for i in range(300):  # 30 s at 10 Hz, armed throughout
            stamp = struct.pack(">Q", T0_US + i * 100_000)
            heartbeat = mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_QUADROTOR,
                mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                armed,
                5,
                mavlink2.MAV_STATE_ACTIVE,
                3,
            )
            status = mavlink2.MAVLink_sys_status_message(
                sensors, sensors, sensors, 350, 15800, 1800, 80, 0, 0, 0, 0, 0, 0
            )
            f.write(stamp + heartbeat.pack(mav))
            f.write(stamp + status.pack(mav))
    return path


def _rc_loss(tmp_path, rc_bit: int) -> dict:
    path = _tlog(tmp_path / f"rc{rc_bit}.tlog", rc_bit)
    store = import_to_store(path, tmp_path / f"store{rc_bit}")
    return {r["name"]: r for r in run_checks(store)}["rc_loss"]


def test_no_receiver_reported_is_not_checked(tmp_path):
    result = _rc_loss(tmp_path, 0)
    assert result["status"] == "not_checked", result
    assert result["reason"].startswith("no "), result


def test_a_healthy_receiver_reported_passes(tmp_path):
    result = _rc_loss(tmp_path, mavlink2.MAV_SYS_STATUS_SENSOR_RC_RECEIVER)
    assert result["status"] == "pass", result

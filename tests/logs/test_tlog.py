import struct

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from logs import LogFormatError, find_special, import_log

T0_US = 1_700_000_000_000_000


def write_tlog(path, n=50, t0_us=T0_US):
    """A .tlog as ground stations write it: 8-byte big-endian µs stamp + MAVLink packet."""
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    with open(path, "wb") as f:
        for i in range(n):
            stamp = struct.pack(">Q", t0_us + i * 100_000)
            msgs = [
                mavlink2.MAVLink_attitude_message(i * 100, 0.01 * i, -0.02 * i, 1.5, 0.0, 0.0, 0.0),
                mavlink2.MAVLink_global_position_int_message(
                    i * 100, 473977420 + i, 85455940, 500_000, 10_000 + i, 1, 2, 3, 9000
                ),
            ]
            if i % 10 == 0:
                msgs.append(
                    mavlink2.MAVLink_sys_status_message(
                        0, 0, 0, 500, 12000, 100, 90 - i // 10, 0, 0, 0, 0, 0, 0
                    )
                )
                msgs.append(mavlink2.MAVLink_statustext_message(6, f"step {i}".encode()))
            for msg in msgs:
                f.write(stamp + msg.pack(mav))
    return path


def test_tlog_messages_become_layers_with_recorder_time(tmp_path):
    log = import_log(write_tlog(tmp_path / "flight.tlog"))
    assert set(log.layers) == {"ATTITUDE", "GLOBAL_POSITION_INT", "SYS_STATUS", "STATUSTEXT"}
    roll = log.series["ATTITUDE/roll"]
    assert roll.time_source == "recorder"
    assert roll.unit == "rad"
    np.testing.assert_allclose(roll.values, np.float32(np.arange(50) * 0.01), rtol=1e-6)
    np.testing.assert_array_equal(roll.times, (T0_US + np.arange(50) * 100_000) * 1000)
    assert log.series["GLOBAL_POSITION_INT/lat"].values[3] == 473977423
    assert log.series["STATUSTEXT/text"].values.tolist() == [f"step {i}" for i in range(0, 50, 10)]
    assert log.series["SYS_STATUS/battery_remaining"].values.tolist() == [90, 89, 88, 87, 86]


def test_tlog_special_quantities_are_tagged(tmp_path):
    special = find_special(import_log(write_tlog(tmp_path / "flight.tlog")))
    assert special["rotation"] == ["ATTITUDE/roll", "ATTITUDE/pitch", "ATTITUDE/yaw"]
    assert special["battery"] == ["SYS_STATUS/battery_remaining"]
    assert special["gps"][:2] == ["GLOBAL_POSITION_INT/lat", "GLOBAL_POSITION_INT/lon"]


def test_tlog_is_recognised_by_content_without_its_extension(tmp_path):
    log = import_log(write_tlog(tmp_path / "upload-1234.dat"))
    assert log.format == "tlog"


def test_tlog_cut_mid_packet_keeps_the_packets_before(tmp_path):
    path = write_tlog(tmp_path / "flight.tlog")
    path.write_bytes(path.read_bytes()[:-7])
    log = import_log(path)
    assert len(log.series["ATTITUDE/roll"].values) == 50
    assert len(log.series["GLOBAL_POSITION_INT/lat"].values) == 49


def test_tlog_truncated_to_its_first_stamp_is_rejected(tmp_path):
    path = write_tlog(tmp_path / "flight.tlog")
    path.write_bytes(path.read_bytes()[:12])
    with pytest.raises(LogFormatError, match="no MAVLink messages"):
        import_log(path)


def write_tlog_of_several_senders(path):
    """What a ground station records: the vehicle's messages (1, 1) beside its own
    HEARTBEAT and SYSTEM_TIME (255, 190) and a gimbal's HEARTBEAT (1, 154)."""
    vehicle = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    station = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    gimbal = mavlink2.MAVLink(None, srcSystem=1, srcComponent=154)
    invalid, ardupilot = mavlink2.MAV_AUTOPILOT_INVALID, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
    with open(path, "wb") as f:
        for i in range(20):
            stamp = struct.pack(">Q", T0_US + i * 100_000)
            sent = [
                (vehicle, mavlink2.MAVLink_heartbeat_message(2, ardupilot, 209, 5, 4, 3)),
                (vehicle, mavlink2.MAVLink_system_time_message(T0_US + i, 1000 + i)),
                (vehicle, mavlink2.MAVLink_attitude_message(i, 0.1, 0.2, 0.3, 0, 0, 0)),
                (station, mavlink2.MAVLink_heartbeat_message(6, invalid, 0, 0, 0, 3)),
                (station, mavlink2.MAVLink_system_time_message(T0_US + i, 0)),
                (gimbal, mavlink2.MAVLink_heartbeat_message(26, invalid, 0, 0, 0, 3)),
            ]
            for sender, msg in sent:
                f.write(stamp + msg.pack(sender))
    return path


def test_each_sender_keeps_its_own_series_and_the_vehicle_its_plain_names(tmp_path):
    log = import_log(write_tlog_of_several_senders(tmp_path / "recorded.tlog"))
    assert set(log.layers) == {
        "HEARTBEAT",
        "SYSTEM_TIME",
        "ATTITUDE",
        "HEARTBEAT[255:190]",
        "SYSTEM_TIME[255:190]",
        "HEARTBEAT[1:154]",
    }
    # The vehicle's type and mode are its own, not interleaved with the station's.
    assert set(log.series["HEARTBEAT/type"].values.tolist()) == {2}
    assert set(log.series["HEARTBEAT/custom_mode"].values.tolist()) == {5}
    assert log.series["SYSTEM_TIME/time_boot_ms"].values.tolist() == list(range(1000, 1020))
    assert set(log.series["HEARTBEAT[255:190]/type"].values.tolist()) == {6}
    assert len(log.series["HEARTBEAT[1:154]/type"].values) == 20
    assert (
        log.series["SYSTEM_TIME[255:190]/time_unix_usec"].unit
        == log.series["SYSTEM_TIME/time_unix_usec"].unit
    )
    assert find_special(log)["rotation"] == ["ATTITUDE/roll", "ATTITUDE/pitch", "ATTITUDE/yaw"]


def test_the_vehicle_is_the_autopilot_even_when_the_station_sent_more(tmp_path):
    path = write_tlog_of_several_senders(tmp_path / "recorded.tlog")
    station = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    invalid = mavlink2.MAV_AUTOPILOT_INVALID
    with open(path, "ab") as f:
        for i in range(200):
            stamp = struct.pack(">Q", T0_US + 2_000_000 + i * 10_000)
            f.write(
                stamp + mavlink2.MAVLink_heartbeat_message(6, invalid, 0, 0, 0, 3).pack(station)
            )
    log = import_log(path)
    assert set(log.series["HEARTBEAT/type"].values.tolist()) == {2}
    assert len(log.series["HEARTBEAT[255:190]/type"].values) == 220

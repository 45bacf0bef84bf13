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

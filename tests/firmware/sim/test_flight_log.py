"""The simulated autopilots log each flight in their own format and serve it over
MAVLink's log protocol; the files are read back with the formats' own readers (pyulog,
pymavlink's DFReader), not ours."""

from __future__ import annotations

import pytest
from pymavlink import DFReader
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pyulog import ULog

from firmware.sim.flight_log import LOG_DATA_BYTES
from tests.firmware.sim.test_mavlink_autopilots import Ground

ALTITUDE = 6.0


def _fly_and_land(ground: Ground) -> None:
    if not ground.session.px4:  # LAND, where the last flight ended, is not armable
        assert ground.copter_mode("GUIDED") == 0
    ground.fly_up(ALTITUDE)
    assert ground.command(mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0) == 0
    ground.run(ALTITUDE + 8)
    assert not ground.session.armed  # landed and disarmed by itself


def _fetch(ground: Ground) -> tuple[list, bytes]:
    """LOG_REQUEST_LIST, then the newest log in windows of 10 LOG_DATA, then the end."""
    ground.inbox.clear()
    ground.send("log_request_list", 1, 1, 0, 0xFFFF)
    entries = [m for m in ground.inbox if m.get_type() == "LOG_ENTRY"]
    newest = next(e for e in entries if e.id == e.last_log_num)
    data, offset = bytearray(), 0
    for _ in range(newest.size // LOG_DATA_BYTES + 10):
        if offset >= newest.size:
            break
        ground.inbox.clear()
        ground.send("log_request_data", 1, 1, newest.id, offset, 10 * LOG_DATA_BYTES)
        ground.run(0.05)
        for m in ground.inbox:
            if m.get_type() == "LOG_DATA" and m.ofs == offset:
                data += bytes(m.data[: m.count])
                offset += m.count
    ground.send("log_request_end", 1, 1)
    return entries, bytes(data)


def test_px4_serves_the_flight_as_a_ulog(tmp_path):
    ground = Ground("px4")
    ground.inbox.clear()
    ground.send("log_request_list", 1, 1, 0, 0xFFFF)
    assert [m.num_logs for m in ground.inbox if m.get_type() == "LOG_ENTRY"] == [0]
    _fly_and_land(ground)
    entries, data = _fetch(ground)
    assert [(e.id, e.num_logs) for e in entries] == [(1, 1)]
    assert len(data) == entries[0].size
    path = tmp_path / "flight.ulg"
    path.write_bytes(data)
    ulog = ULog(str(path))
    topics = {d.name: d for d in ulog.data_list}
    assert {"vehicle_status", "sensor_combined", "battery_status"} <= set(topics)
    height = -topics["vehicle_local_position"].data["z"]
    assert height.max() == pytest.approx(ALTITUDE, abs=0.5)
    accel_z = topics["sensor_combined"].data["accelerometer_m_s2[2]"]
    assert accel_z.mean() == pytest.approx(-9.81, abs=0.5)


def test_ardupilot_serves_the_flight_as_a_dataflash_bin(tmp_path):
    ground = Ground("ardupilot")
    _fly_and_land(ground)
    _fly_and_land(ground)
    entries, data = _fetch(ground)
    assert [(e.id, e.num_logs) for e in entries] == [(1, 2), (2, 2)]
    path = tmp_path / "flight.bin"
    path.write_bytes(data)
    reader = DFReader.DFReader_binary(str(path))
    heights, events = [], []
    while (m := reader.recv_msg()) is not None:
        if m.get_type() == "POS":
            heights.append(m.RelHomeAlt)
        elif m.get_type() == "EV":
            events.append(m.Id)
    assert events == [10, 11]  # armed, disarmed
    assert max(heights) == pytest.approx(ALTITUDE, abs=0.5)

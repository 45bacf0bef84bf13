from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog

from logs import LogFormatError, find_special, import_log
from logs.analysis import quaternion
from logs.synth import synthetic_ulog, write_ulog
from tests.support.paths import REAL_ULOGS

REAL_LOGS = sorted(REAL_ULOGS.glob("*.ulg"))
# Both real logs must be found: an empty list would silently parametrise nothing.
assert len(REAL_LOGS) == 2, f"expected the two PX4 logs in {REAL_ULOGS}"


def _assert_equal_to_pyulog(path: Path) -> None:
    log = import_log(path)
    reference = ULog(str(path))
    counts: dict[str, int] = {}
    for d in reference.data_list:
        counts[d.name] = counts.get(d.name, 0) + 1
    checked = 0
    for d in reference.data_list:
        layer = d.name if counts[d.name] == 1 else f"{d.name}_{d.multi_id}"
        for field, values in d.data.items():
            if field == "timestamp":
                continue
            series = log.series[f"{layer}/{field}"]
            np.testing.assert_array_equal(series.values, values)
            np.testing.assert_array_equal(series.times, d.data["timestamp"].astype(np.int64) * 1000)
            assert series.time_source == "board"
            checked += 1
    derived = [s for s in log.series if s.startswith("logging/") or "/euler/" in s]
    assert checked == len(log.series) - len(derived)


@pytest.mark.parametrize("path", REAL_LOGS, ids=lambda p: p.name)
def test_real_px4_logs_read_the_same_values_as_pyulog(path):
    assert len(REAL_LOGS) == 2
    _assert_equal_to_pyulog(path)


def test_real_px4_log_messages_become_a_text_layer():
    log = import_log(REAL_LOGS[1])
    reference = ULog(str(REAL_LOGS[1]))
    assert log.series["logging/message"].values.tolist() == [
        m.message for m in reference.logged_messages
    ]
    level = log.series["logging/level"]
    assert (
        level.labels[int(level.values[0])] == reference.logged_messages[0].log_level_str().lower()
    )


def test_generated_ulog_is_read_by_pyulog_and_by_us_alike(tmp_path):
    path = tmp_path / "synthetic.ulg"
    synthetic_ulog(path, seconds=3)
    _assert_equal_to_pyulog(path)
    log = import_log(path)
    assert log.series["logging/message"].values.tolist() == ["Takeoff detected", "Low battery"]
    assert len(log.series["sensor_combined/gyro_rad[2]"].values) == 750
    assert find_special(log)["gps"] == [
        "vehicle_gps_position/lat",
        "vehicle_gps_position/lon",
        "vehicle_gps_position/alt",
    ]


def test_ulog_writer_round_trips_exact_values(tmp_path):
    arr = np.zeros(
        3, dtype=[("timestamp", "<u8"), ("alt", "<f8"), ("flags", "u1"), ("q", "(4,)<f4")]
    )
    arr["timestamp"] = [10, 20, 30]
    arr["alt"] = [1.5, 2.5, -3.25]
    arr["flags"] = [1, 2, 255]
    arr["q"] = [[1, 0, 0, 0]] * 3
    path = tmp_path / "tiny.ulg"
    write_ulog(path, {"altitude_probe": arr})
    log = import_log(path)
    assert log.series["altitude_probe/alt"].values.tolist() == [1.5, 2.5, -3.25]
    assert log.series["altitude_probe/flags"].values.tolist() == [1, 2, 255]
    assert log.series["altitude_probe/q[0]"].values.tolist() == [1, 1, 1]
    assert log.series["altitude_probe/alt"].times.tolist() == [10_000, 20_000, 30_000]


def test_ulog_truncated_in_its_header_is_rejected(tmp_path):
    path = tmp_path / "cut.ulg"
    path.write_bytes(REAL_LOGS[0].read_bytes()[:12])
    with pytest.raises(LogFormatError, match="not a valid PX4 ULog"):
        import_log(path)


def test_ulog_truncated_before_any_data_is_rejected(tmp_path):
    path = tmp_path / "cut.ulg"
    path.write_bytes(REAL_LOGS[0].read_bytes()[:2000])
    with pytest.raises(LogFormatError, match="contains no data"):
        import_log(path)


def test_ulog_cut_mid_flight_keeps_the_data_before_the_cut(tmp_path):
    # A log cut short by a crash is exactly what the viewer is for: keep what is there.
    data = REAL_LOGS[0].read_bytes()
    path = tmp_path / "crash.ulg"
    path.write_bytes(data[: len(data) // 2])
    full, cut = import_log(REAL_LOGS[0]), import_log(path)
    series = cut.series["sensor_combined/gyro_rad[0]"]
    assert 0 < len(series.values) < len(full.series["sensor_combined/gyro_rad[0]"].values)


def test_px4_attitude_quaternion_also_gives_yaw_pitch_roll(tmp_path):
    yaw, pitch, roll = np.radians([[120.0, -30.0], [10.0, 45.0], [-20.0, 5.0]])
    arr = np.zeros(2, dtype=[("timestamp", "<u8"), ("q", "(4,)<f4")])
    arr["timestamp"] = [1, 2]
    arr["q"] = quaternion(yaw, pitch, roll)
    path = tmp_path / "att.ulg"
    write_ulog(path, {"vehicle_attitude": arr})
    log = import_log(path)
    for name, expected in (("yaw", yaw), ("pitch", pitch), ("roll", roll)):
        np.testing.assert_allclose(
            log.series[f"vehicle_attitude/euler/{name}"].values, expected, atol=1e-6
        )
    assert find_special(log)["rotation"] == [
        f"vehicle_attitude/euler/{n}" for n in ("roll", "pitch", "yaw")
    ]


def test_yaw_pitch_roll_of_a_long_log_are_computed_block_by_block(tmp_path, monkeypatch):
    from logs.importers import ulog

    monkeypatch.setattr(ulog, "EULER_BLOCK", 7)  # rows in several blocks and a partial one
    rng = np.random.default_rng(3)
    yaw, pitch, roll = rng.uniform(-1.5, 1.5, (3, 30))
    arr = np.zeros(30, dtype=[("timestamp", "<u8"), ("q", "(4,)<f4")])
    arr["timestamp"] = np.arange(1, 31)
    arr["q"] = quaternion(yaw, pitch, roll)
    path = tmp_path / "long.ulg"
    write_ulog(path, {"vehicle_attitude": arr})
    log = import_log(path)
    for name, expected in (("yaw", yaw), ("pitch", pitch), ("roll", roll)):
        values = log.series[f"vehicle_attitude/euler/{name}"].values
        assert values.dtype == np.float32  # the quaternion's own precision
        np.testing.assert_allclose(values, expected, atol=1e-5)


def test_tagged_log_messages_join_the_others_in_file_order(tmp_path):
    """PX4 logs a module's strings as tagged messages ('C': level, tag, time, text) beside
    the plain ones ('L'); pyulog keeps them apart by tag, the viewer shows both."""
    import struct

    path = tmp_path / "tagged.ulg"
    arr = np.zeros(2, dtype=[("timestamp", "<u8"), ("alt", "<f4")])
    arr["timestamp"] = [1_000, 2_000_000]
    write_ulog(path, {"altitude_probe": arr}, messages=[(1_500, 6, "plain one")])
    text = b"tagged one"
    payload = struct.pack("<BHQ", ord("4"), 7, 2_500_000) + text  # level as ULog writes it
    with open(path, "ab") as f:
        f.write(struct.pack("<HB", len(payload), ord("C")) + payload)
    reference = ULog(str(path))
    assert [m.message for m in reference.logged_messages_tagged[7]] == ["tagged one"]
    log = import_log(path)
    assert log.series["logging/message"].values.tolist() == ["plain one", "tagged one"]
    assert log.series["logging/message"].times.tolist() == [1_500_000, 2_500_000_000]
    level = log.series["logging/level"]
    assert (
        level.labels[int(level.values[1])]
        == reference.logged_messages_tagged[7][0].log_level_str().lower()
    )


def test_a_parameter_changed_in_flight_is_kept_at_its_last_value(tmp_path):
    """A `P` message in the data section is a change made in flight (pyulog's
    changed_parameters); the log's parameters, like every format's, end at the last value."""
    import struct

    path = tmp_path / "tuned.ulg"
    arr = np.zeros(2, dtype=[("timestamp", "<u8"), ("alt", "<f4")])
    arr["timestamp"] = [1_000, 2_000_000]
    write_ulog(path, {"altitude_probe": arr}, parameters={"MPC_XY_VEL_MAX": 12.0, "COM_RC_IN": 1})
    with open(path, "ab") as f:
        for value in (10.0, 8.0):
            key = b"float MPC_XY_VEL_MAX"
            payload = bytes([len(key)]) + key + struct.pack("<f", value)
            f.write(struct.pack("<HB", len(payload), ord("P")) + payload)
    reference = ULog(str(path))
    assert [(name, value) for _, name, value in reference.changed_parameters] == [
        ("MPC_XY_VEL_MAX", 10.0),
        ("MPC_XY_VEL_MAX", 8.0),
    ]
    parameters = import_log(path).metadata["parameters"]
    assert parameters == {"MPC_XY_VEL_MAX": 8.0, "COM_RC_IN": 1}

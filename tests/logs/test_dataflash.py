import numpy as np
import pytest
from pymavlink import mavutil

from logs import LogFormatError, find_special, import_log
from logs.synth import dataflash_dtype, synthetic_dataflash, write_dataflash


def _pymavlink_columns(path):
    conn = mavutil.mavlink_connection(str(path))
    out: dict[str, dict[str, list]] = {}
    while (msg := conn.recv_match()) is not None:
        kind = msg.get_type()
        if msg.fmt.instance_field is not None:
            kind = f"{kind}[{getattr(msg, msg.fmt.instance_field)}]"
        if kind == "FMT":
            continue
        cols = out.setdefault(kind, {})
        for name in msg.get_fieldnames():
            cols.setdefault(name, []).append(getattr(msg, name))
    return out


@pytest.fixture
def bin_log(tmp_path):
    path = tmp_path / "flight.bin"
    synthetic_dataflash(path, seconds=2, rate_hz=50)
    return path


def test_dataflash_values_equal_pymavlinks_full_decode(bin_log):
    log = import_log(bin_log)
    reference = _pymavlink_columns(bin_log)
    checked = 0
    for kind, cols in reference.items():
        times = np.asarray(cols["TimeUS"], dtype=np.int64) * 1000
        for name, values in cols.items():
            if name == "TimeUS":
                continue
            series = log.series[f"{kind}/{name}"]
            if series.kind == "text":
                assert series.values.tolist() == values
            else:
                np.testing.assert_allclose(series.values, values, rtol=1e-12)
            np.testing.assert_array_equal(series.times, times)
            checked += 1
    assert checked == len(log.series) > 20


def test_dataflash_scaled_types_become_physical_values(tmp_path):
    arr = np.zeros(2, dtype=dataflash_dtype("QLcE", ["TimeUS", "Lat", "Roll", "Spd"]))
    arr["TimeUS"] = [1_000, 2_000]
    arr["Lat"] = [501234567, -12345678]
    arr["Roll"] = [-1234, 4500]
    arr["Spd"] = [150, 0]
    path = tmp_path / "scaled.bin"
    write_dataflash(path, {"POS": ("QLcE", arr)})
    log = import_log(path)
    np.testing.assert_allclose(log.series["POS/Lat"].values, [50.1234567, -1.2345678])
    np.testing.assert_allclose(log.series["POS/Roll"].values, [-12.34, 45.0])
    np.testing.assert_allclose(log.series["POS/Spd"].values, [1.5, 0.0])
    assert log.series["POS/Lat"].times.tolist() == [1_000_000, 2_000_000]


def test_dataflash_units_and_instances_come_from_fmtu(bin_log):
    log = import_log(bin_log)
    assert log.series["IMU[1]/AccZ"].unit == "m/s/s"
    assert log.series["GPS/Lat"].unit == "deglatitude"
    assert log.series["IMU[0]/I"].values.tolist() == [0] * 50
    times = log.series["IMU[1]/AccX"].times
    assert times[0] == 520_000_000 and set(np.diff(times).tolist()) == {40_000_000}


def test_dataflash_special_quantities_are_tagged(bin_log):
    special = find_special(import_log(bin_log))
    assert special["rotation"] == ["ATT/Roll", "ATT/Pitch", "ATT/Yaw"]
    assert special["gps"] == ["GPS/Lat", "GPS/Lng", "GPS/Alt"]
    assert special["acceleration"] == ["IMU[0]/AccX", "IMU[0]/AccY", "IMU[0]/AccZ"]
    assert special["motors"] == ["RCOU/C1", "RCOU/C2", "RCOU/C3", "RCOU/C4"]


def test_dataflash_truncated_last_record_is_dropped_and_reported(bin_log):
    full = import_log(bin_log)
    bin_log.write_bytes(bin_log.read_bytes()[:-5])
    cut = import_log(bin_log)
    assert "The last record is truncated and was dropped." in cut.warnings
    lost = sum(len(s.values) for s in full) - sum(len(s.values) for s in cut)
    assert 0 < lost <= 9  # one record's fields


def test_dataflash_garbage_between_records_is_skipped(bin_log):
    data = bytearray(bin_log.read_bytes())
    at = data.index(b"\xa3\x95", 5000)  # a record boundary
    data[at:at] = b"\x00\x01garbage\xa3"
    bin_log.write_bytes(bytes(data))
    log = import_log(bin_log)
    assert any("Skipped" in w for w in log.warnings)
    assert len(log.series["IMU[0]/GyrX"].values) + len(log.series["IMU[1]/GyrX"].values) == 100


def test_dataflash_truncated_inside_its_formats_is_rejected(bin_log):
    bin_log.write_bytes(bin_log.read_bytes()[:60])
    with pytest.raises(LogFormatError, match="no FMT records"):
        import_log(bin_log)


def test_dataflash_corrupt_fmt_loses_only_its_message_type(bin_log):
    data = bytearray(bin_log.read_bytes())
    at = data.index(b"ATT\x00")  # the FMT record describing ATT
    data[at + 4 : at + 10] = b"QccCc?"  # an unknown format character
    bin_log.write_bytes(bytes(data))
    log = import_log(bin_log)
    assert not any(p.startswith("ATT/") for p in log.series)
    assert len(log.series["GPS/Lat"].values) == 20
    assert any(
        "Ignored a corrupt FMT record: FMT of ATT: unsupported format character '?'" in w
        for w in log.warnings
    )


def test_a_log_whose_only_format_is_corrupt_says_what_is_wrong_with_it(tmp_path):
    """The FMT of FMT, then one FMT whose format string needs 9 bytes in a 6-byte record."""
    fmt_of_fmt = bytes([0xA3, 0x95, 0x80, 0x80, 89]) + b"FMT\0" + b"BBnNZ".ljust(16, b"\0")
    fmt_of_fmt += b"Type,Length,Name,Format,Columns".ljust(64, b"\0")
    tst = bytes([0xA3, 0x95, 0x80, 0x81, 6]) + b"TST\0" + b"QB".ljust(16, b"\0")
    tst += b"TimeUS,V".ljust(64, b"\0")
    path = tmp_path / "one-bad-format.bin"
    path.write_bytes(fmt_of_fmt + tst + bytes([0xA3, 0x95, 0x81, 1, 2, 3]))
    with pytest.raises(LogFormatError, match="no FMT record we can use: FMT of TST: format 'QB'"):
        import_log(path)

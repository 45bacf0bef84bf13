"""Writers for synthetic PX4 ULog and ArduPilot DataFlash logs (tests and benchmarks).

Both write vectorised: each topic's records are packed with one structured dtype and the
streams are interleaved in time blocks, so a 100 MB log takes about a second to write.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from logs.importers.dataflash import FMT_LEN, FMT_TYPE, FORMAT_CHARS

ULOG_TYPES = {
    "i1": "int8_t",
    "u1": "uint8_t",
    "i2": "int16_t",
    "u2": "uint16_t",
    "i4": "int32_t",
    "u4": "uint32_t",
    "i8": "int64_t",
    "u8": "uint64_t",
    "f4": "float",
    "f8": "double",
    "b1": "bool",
}


def _ulog_field(name: str, dt: np.dtype) -> str:
    if dt.subdtype is not None:
        base, shape = dt.subdtype
        return f"{ULOG_TYPES[base.str[1:]]}[{shape[0]}] {name}"
    return f"{ULOG_TYPES[dt.str[1:]]} {name}"


def _msg(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _blocks(times: list[np.ndarray], block: int) -> list[tuple[int, int, int]]:
    """(stream, start, stop) slices so records come out roughly in time order."""
    t0 = min(int(t[0]) for t in times if len(t))
    t1 = max(int(t[-1]) for t in times if len(t))
    edges = np.arange(t0, t1 + block + 1, block)
    bounds = [np.searchsorted(t, edges) for t in times]
    out = []
    for k in range(len(edges) - 1):
        for stream, b in enumerate(bounds):
            if b[k + 1] > b[k]:
                out.append((stream, int(b[k]), int(b[k + 1])))
    return out


def write_ulog(
    path: Path,
    topics: dict[str, np.ndarray],
    *,
    messages: list[tuple[int, int, str]] = (),  # type: ignore[assignment]
    info: dict[str, str] | None = None,
    block_us: int = 1_000_000,
    parameters: dict[str, int | float] | None = None,
) -> None:
    """Write a ULog (version 1). Each topic is a structured array whose first field is
    `timestamp` (uint64 µs); messages are (timestamp µs, level 0-7, text); parameters
    are `P` messages, int32_t for a Python int, else float."""
    out = bytearray(b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0))
    # Flag bits message: no incompatible flags, no appended data.
    out += _msg(b"B", bytes(8) + bytes(8) + bytes(24))
    for key, value in (info or {"sys_name": "Skyhive synthetic"}).items():
        k = f"char[{len(value)}] {key}".encode()
        out += _msg(b"I", bytes([len(k)]) + k + value.encode())
    for key, value in (parameters or {}).items():
        kind, packed_value = (
            ("int32_t", struct.pack("<i", value))
            if isinstance(value, int)
            else ("float", struct.pack("<f", value))
        )
        k = f"{kind} {key}".encode()
        out += _msg(b"P", bytes([len(k)]) + k + packed_value)
    for name, arr in topics.items():
        fields = ";".join(_ulog_field(n, arr.dtype.fields[n][0]) for n in arr.dtype.names)
        out += _msg(b"F", f"{name}:{fields};".encode())
    packed, times = [], []
    for msg_id, (name, arr) in enumerate(topics.items()):
        out += _msg(b"A", struct.pack("<BH", 0, msg_id) + name.encode())
        header = np.dtype([("size", "<u2"), ("type", "u1"), ("msg_id", "<u2")])
        rec = np.zeros(len(arr), dtype=np.dtype([("h", header), ("p", arr.dtype)]))
        rec["h"]["size"] = 2 + arr.dtype.itemsize
        rec["h"]["type"] = ord("D")
        rec["h"]["msg_id"] = msg_id
        rec["p"] = arr
        packed.append(rec)
        times.append(arr["timestamp"].astype(np.int64))
    logging = list(messages)
    with open(path, "wb") as f:
        f.write(out)
        for stream, start, stop in _blocks(times, block_us):
            f.write(packed[stream][start:stop].tobytes())
            lo, hi = int(times[stream][start]), int(times[stream][stop - 1])
            while logging and logging[0][0] <= hi and logging[0][0] >= lo:
                ts, level, text = logging.pop(0)
                f.write(_msg(b"L", struct.pack("<BQ", ord("0") + level, ts) + text.encode()))
        for ts, level, text in logging:
            f.write(_msg(b"L", struct.pack("<BQ", ord("0") + level, ts) + text.encode()))


def _fmt_record(type_: int, length: int, name: str, chars: str, columns: str) -> bytes:
    return struct.pack(
        "<BBBBB4s16s64s",
        0xA3,
        0x95,
        FMT_TYPE,
        type_,
        length,
        name.encode(),
        chars.encode(),
        columns.encode(),
    )


def dataflash_dtype(chars: str, columns: list[str]) -> np.dtype:
    """The stored (unscaled) record layout of a DataFlash message."""
    return np.dtype([(c, FORMAT_CHARS[ch][0]) for ch, c in zip(chars, columns, strict=True)])


def write_dataflash(
    path: Path, messages: dict[str, tuple[str, np.ndarray]], *, block_us: int = 1_000_000
) -> None:
    """Write an ArduPilot .bin. messages: name -> (format chars, structured array of stored
    values with the column names; TimeUS first for timed messages)."""
    out = bytearray(
        _fmt_record(FMT_TYPE, FMT_LEN, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    )
    packed, times = [], []
    for number, (name, (chars, arr)) in enumerate(messages.items()):
        type_ = 129 + number
        length = 3 + arr.dtype.itemsize
        out += _fmt_record(type_, length, name, chars, ",".join(arr.dtype.names))
        head = np.dtype([("h1", "u1"), ("h2", "u1"), ("type", "u1")])
        rec = np.zeros(len(arr), dtype=np.dtype([("h", head), ("p", arr.dtype)]))
        rec["h"]["h1"], rec["h"]["h2"], rec["h"]["type"] = 0xA3, 0x95, type_
        rec["p"] = arr
        packed.append(rec)
        names = arr.dtype.names
        times.append(
            arr["TimeUS"].astype(np.int64) if "TimeUS" in names else np.zeros(len(arr), np.int64)
        )
    with open(path, "wb") as f:
        f.write(out)
        for stream, start, stop in _blocks(times, block_us):
            f.write(packed[stream][start:stop].tobytes())


def synthetic_ulog(path: Path, *, seconds: float, rate_hz: float = 250.0) -> None:
    """A ULog with IMU, attitude, local position, GPS and battery topics."""
    rng = np.random.default_rng(7)

    def topic(fields: list[tuple[str, str]], hz: float) -> np.ndarray:
        n = int(seconds * hz)
        arr = np.zeros(n, dtype=np.dtype([("timestamp", "<u8"), *fields]))
        arr["timestamp"] = (np.arange(n) * (1e6 / hz)).astype(np.uint64) + 1_000_000
        for name in arr.dtype.names[1:]:
            shape = arr[name].shape
            arr[name] = (
                rng.normal(size=shape).astype(arr[name].dtype)
                if arr[name].dtype.kind == "f"
                else rng.integers(0, 100, size=shape)
            )
        return arr

    topics = {
        "sensor_combined": topic(
            [
                ("gyro_rad", "(3,)<f4"),
                ("gyro_integral_dt", "<u4"),
                ("accelerometer_m_s2", "(3,)<f4"),
                ("accelerometer_integral_dt", "<u4"),
            ],
            rate_hz,
        ),
        "vehicle_attitude": topic(
            [("q", "(4,)<f4"), ("delta_q_reset", "(4,)<f4"), ("quat_reset_counter", "u1")], rate_hz
        ),
        "vehicle_local_position": topic(
            [
                ("x", "<f4"),
                ("y", "<f4"),
                ("z", "<f4"),
                ("vx", "<f4"),
                ("vy", "<f4"),
                ("vz", "<f4"),
                ("heading", "<f4"),
            ],
            rate_hz / 2,
        ),
        "vehicle_gps_position": topic(
            [
                ("lat", "<i4"),
                ("lon", "<i4"),
                ("alt", "<i4"),
                ("eph", "<f4"),
                ("satellites_used", "u1"),
            ],
            10,
        ),
        "battery_status": topic(
            [("voltage_v", "<f4"), ("current_a", "<f4"), ("remaining", "<f4")], 10
        ),
    }
    write_ulog(
        path, topics, messages=[(2_000_000, 6, "Takeoff detected"), (3_000_000, 4, "Low battery")]
    )


# UNIT and FMTU contents: unit of each id, unit ids of each message's columns (# marks
# the instance column).
_DATAFLASH_UNITS = {
    "s": "s",
    "E": "rad/s",
    "o": "m/s/s",
    "d": "deg",
    "D": "deglatitude",
    "U": "deglongitude",
    "m": "m",
    "n": "m/s",
    "v": "V",
    "A": "A",
    "a": "Ah",
    "%": "%",
    "Y": "PWM",
    "-": "",
    "#": "instance",
}
_DATAFLASH_UNIT_IDS = {
    "IMU": "sEEEooo#",
    "ATT": "sddddd",
    "GPS": "s---DUmnn",
    "BAT": "svAa%",
    "RCOU": "sYYYY",
    "MSG": "s-",
}


def synthetic_dataflash(
    path: Path, *, seconds: float, rate_hz: float = 400.0
) -> dict[str, tuple[str, np.ndarray]]:
    """An ArduPilot .bin with two IMUs, ATT, GPS, BAT, RCOU, MSG (scaled types c/C/e/E/L
    included) and the UNIT/FMTU messages that give units and mark instance columns."""
    rng = np.random.default_rng(11)
    units, unit_ids = _DATAFLASH_UNITS, _DATAFLASH_UNIT_IDS
    spec = {
        "UNIT": ("QbZ", "TimeUS,Id,Label", None),
        "FMTU": ("QBNN", "TimeUS,FmtType,UnitIds,MultIds", None),
        "IMU": ("QffffffB", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,I", rate_hz),
        "ATT": ("QccCcc", "TimeUS,Roll,Pitch,Yaw,DesRoll,DesPitch", rate_hz / 4),
        "GPS": ("QBIHLLeEe", "TimeUS,Status,GMS,GWk,Lat,Lng,Alt,Spd,VZ", 10),
        "BAT": ("Qffdb", "TimeUS,Volt,Curr,CurrTot,RemPct", 10),
        "RCOU": ("QHHHH", "TimeUS,C1,C2,C3,C4", rate_hz / 8),
        "MSG": ("QZ", "TimeUS,Message", 0.5),
    }
    type_ids = {name: 129 + number for number, name in enumerate(spec)}
    messages = {}
    for name, (chars, cols, hz) in spec.items():
        columns = cols.split(",")
        n = {"UNIT": len(units), "FMTU": len(unit_ids)}.get(name) or max(int(seconds * hz), 1)
        arr = np.zeros(n, dtype=dataflash_dtype(chars, columns))
        arr["TimeUS"] = (np.arange(n) * (1e6 / hz)).astype(np.uint64) + 500_000 if hz else 0
        for c in columns[1:]:
            kind = arr[c].dtype.kind
            if kind == "f":
                arr[c] = rng.normal(size=n)
            elif kind == "S":
                arr[c] = [f"message {i}".encode() for i in range(n)]
            else:
                info = np.iinfo(arr[c].dtype)
                arr[c] = rng.integers(max(info.min, -30000), min(info.max, 30000), size=n)
        messages[name] = (chars, arr)
    messages["IMU"][1]["I"] = np.arange(len(messages["IMU"][1])) % 2
    messages["UNIT"][1]["Id"] = [ord(k) for k in units]
    messages["UNIT"][1]["Label"] = [v.encode() for v in units.values()]
    messages["FMTU"][1]["FmtType"] = [type_ids[k] for k in unit_ids]
    messages["FMTU"][1]["UnitIds"] = [v.encode() for v in unit_ids.values()]
    messages["FMTU"][1]["MultIds"] = [b"-" * len(v) for v in unit_ids.values()]
    write_dataflash(path, messages)
    return messages

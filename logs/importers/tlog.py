"""MAVLink telemetry logs (.tlog): each record is an 8-byte big-endian µs time stamp written
by the ground station (recorder time) followed by one MAVLink packet; decoded by pymavlink."""

from __future__ import annotations

from pathlib import Path

from pymavlink import mavutil

from logs.importers.base import Limits, LogFormatError, Progress, ProgressTicker
from logs.importers.columns import ColumnCollector
from logs.series import LogData

SPECIAL = {
    "ATTITUDE/roll": "rotation.roll",
    "ATTITUDE/pitch": "rotation.pitch",
    "ATTITUDE/yaw": "rotation.yaw",
    "GLOBAL_POSITION_INT/lat": "gps.lat",
    "GLOBAL_POSITION_INT/lon": "gps.lon",
    "GLOBAL_POSITION_INT/alt": "gps.alt",
    "GLOBAL_POSITION_INT/relative_alt": "altitude",
    "GLOBAL_POSITION_INT/vx": "velocity.x",
    "GLOBAL_POSITION_INT/vy": "velocity.y",
    "GLOBAL_POSITION_INT/vz": "velocity.z",
    "SYS_STATUS/battery_remaining": "battery",
    "SCALED_IMU/xacc": "acceleration.x",
    "SCALED_IMU/yacc": "acceleration.y",
    "SCALED_IMU/zacc": "acceleration.z",
    "SCALED_IMU/xmag": "magnetometer.x",
    "SCALED_IMU/ymag": "magnetometer.y",
    "SCALED_IMU/zmag": "magnetometer.z",
    **{f"SERVO_OUTPUT_RAW/servo{i}_raw": f"motors.{i}" for i in range(1, 5)},
}


class TlogImporter:
    name = "MAVLink telemetry log"
    extensions = (".tlog",)

    def sniff(self, path: Path, head: bytes) -> bool:
        # No magic: a µs Unix time stamp (top byte 0 until the year 2540) then a MAVLink
        # v1 (0xFE) or v2 (0xFD) start byte.
        return len(head) > 9 and head[0] == 0 and head[8] in (0xFE, 0xFD)

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        size = path.stat().st_size
        tick = ProgressTicker(progress, size)
        conn = mavutil.mavlogfile(str(path), robust_parsing=True)
        cols = ColumnCollector()
        log = LogData(format="tlog")
        bad = 0
        try:
            while True:
                msg = conn.recv_msg()
                if msg is None:
                    break
                kind = msg.get_type()
                if kind == "BAD_DATA":
                    bad += 1
                    continue
                t_ns = round(msg._timestamp * 1e6) * 1000
                units = getattr(msg, "fieldunits_by_name", {}) or {}
                fields: dict[str, object] = {}
                for name in msg.get_fieldnames():
                    value = getattr(msg, name)
                    if isinstance(value, list | tuple):
                        for i, item in enumerate(value):
                            if isinstance(item, int | float):
                                fields[f"{name}[{i}]"] = item
                    elif isinstance(value, bytes | str):
                        text = (
                            value.decode("utf-8", "replace") if isinstance(value, bytes) else value
                        )
                        fields[name] = text.rstrip("\0")
                    elif isinstance(value, int | float):
                        fields[name] = value
                    path_key = f"{kind}/{name}"
                    if name in units and units[name]:
                        cols.units[path_key] = units[name]
                    if path_key in SPECIAL:
                        cols.special[path_key] = SPECIAL[path_key]
                cols.add(kind, t_ns, fields)
                tick(conn.f.tell())
        finally:
            conn.close()
        if not cols.layers:
            raise LogFormatError(
                f"The file {path.name!r} holds no MAVLink messages: not a .tlog, or truncated."
            )
        if bad:
            log.warnings.append(f"Skipped {bad} corrupt MAVLink packets.")
        cols.build(log, "recorder")
        return log

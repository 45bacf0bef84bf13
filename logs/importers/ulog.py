"""PX4 ULog, read by the vectorised reader in ulog_reader (same values as pyulog, the parser
PX4 Flight Review uses; bench/bench_logs.py times both on the same file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from logs.importers.base import Limits, LogFormatError, Progress, describe
from logs.importers.ulog_reader import MAGIC, UlogError, read_ulog
from logs.series import LogData, Series, join
from logs.units import ulog_unit

LOG_LEVELS = {
    ord("0") + n: name
    for n, name in enumerate(
        ["emergency", "alert", "critical", "error", "warning", "notice", "info", "debug"]
    )
}

# Reader hints for the dedicated views: (topic, field) of instance 0 -> special key. PX4
# logs both the raw GPS and the estimator's fused position; the fused one is the track.
SPECIAL = {
    ("vehicle_global_position", "lat"): "gps.lat",
    ("vehicle_global_position", "lon"): "gps.lon",
    ("vehicle_global_position", "alt"): ("gps.alt", "altitude"),
    ("vehicle_local_position", "vx"): "velocity.x",
    ("vehicle_local_position", "vy"): "velocity.y",
    ("vehicle_local_position", "vz"): "velocity.z",
    ("sensor_combined", "accelerometer_m_s2[0]"): "acceleration.x",
    ("sensor_combined", "accelerometer_m_s2[1]"): "acceleration.y",
    ("sensor_combined", "accelerometer_m_s2[2]"): "acceleration.z",
    ("vehicle_magnetometer", "magnetometer_ga[0]"): "magnetometer.x",
    ("vehicle_magnetometer", "magnetometer_ga[1]"): "magnetometer.y",
    ("vehicle_magnetometer", "magnetometer_ga[2]"): "magnetometer.z",
    ("battery_status", "remaining"): "battery",
    **{("actuator_outputs", f"output[{i}]"): f"motors.{i}" for i in range(4)},
}


class UlogImporter:
    name = "PX4 ULog"
    extensions = (".ulg", ".ulog")

    def sniff(self, path: Path, head: bytes) -> bool:
        return head.startswith(MAGIC)

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        try:
            ulog = read_ulog(path)
        except UlogError as exc:
            raise LogFormatError(
                f"The file {path.name!r} is not a valid PX4 ULog: {describe(exc)}."
            ) from exc
        progress(0.8)
        log = LogData(format="ulog")
        log.metadata = {
            "info": {k: _plain(v) for k, v in ulog.msg_info_dict.items()},
            "parameters": {k: _plain(v) for k, v in ulog.initial_parameters.items()},
            "start_timestamp_us": int(ulog.start_timestamp),
            # Data the logger could not write (the file's dropout messages), in ms.
            "dropouts_ms": int(ulog.dropouts_ms),
        }
        if ulog.file_corruption:
            log.warnings.append("The log has corrupt data; the readable messages were kept.")
        counts: dict[str, int] = {}
        for d in ulog.data_list:
            counts[d.name] = counts.get(d.name, 0) + 1
        for d in ulog.data_list:
            # A topic with several instances gets one layer per instance.
            layer = d.name if counts[d.name] == 1 else f"{d.name}_{d.multi_id}"
            times = _nanoseconds(d.data["timestamp"])
            for field, values in d.data.items():
                if field == "timestamp":
                    continue
                special = SPECIAL.get((d.name, field)) if d.multi_id == 0 else None
                log.add(
                    Series(
                        join(layer, field),
                        values,
                        times,
                        unit=ulog_unit(d.name, field),
                        time_source="board",
                        kind=_kind(values),
                        special=special,
                    )  # type: ignore[arg-type]
                )
            if d.name == "vehicle_attitude" and d.multi_id == 0 and "q[3]" in d.data:
                self._add_euler(log, layer, d.data, times)
        messages = ulog.logged_messages
        if messages:
            times = np.array([m.timestamp for m in messages], dtype=np.int64) * 1000
            levels = np.array([m.log_level for m in messages], dtype=np.int64)
            text = np.array([m.message for m in messages], dtype=str)
            log.add(Series("logging/message", text, times, time_source="board", kind="text"))
            log.add(
                Series(
                    "logging/level",
                    levels,
                    times,
                    time_source="board",
                    kind="enum",
                    labels=LOG_LEVELS,
                )
            )
        return log

    @staticmethod
    def _add_euler(log: LogData, layer: str, data: dict, times: np.ndarray) -> None:
        """PX4 logs attitude only as a quaternion (w, x, y, z; body FRD to NED); the 3D view
        and the trajectory want yaw, pitch, roll in that order (z, then y, then x)."""
        for name, values in _euler(data).items():
            log.add(
                Series(
                    join(layer, "euler", name),
                    values,
                    times,
                    unit="rad",
                    time_source="board",
                    special=f"rotation.{name}",
                )
            )


# Attitude rows converted at a time: the float64 working copies stay a few MiB however
# long the log.
EULER_BLOCK = 1 << 18


def _euler(data: dict) -> dict[str, np.ndarray]:
    """Roll, pitch and yaw from the logged quaternion, computed in float64 and kept in
    float32, the quaternion's own precision."""
    q = [data[f"q[{i}]"] for i in range(4)]
    angles = {name: np.empty(len(q[0]), dtype=np.float32) for name in ("roll", "pitch", "yaw")}
    for start in range(0, len(q[0]), EULER_BLOCK):
        rows = slice(start, start + EULER_BLOCK)
        w, x, y, z = (component[rows].astype(np.float64) for component in q)
        angles["roll"][rows] = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        angles["pitch"][rows] = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
        angles["yaw"][rows] = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return angles


def _nanoseconds(stamps: np.ndarray) -> np.ndarray:
    """The µs time stamps turned into ns in place, as int64 (what the old int64 product
    gave, wrap-around included): a separate times array would add 8 bytes a message."""
    times = stamps.view(np.int64)
    np.multiply(times, 1000, out=times)
    return times


def _kind(values: np.ndarray) -> str:
    return "double" if values.dtype.kind == "f" else "int"


def _plain(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return value if isinstance(value, int | float | str | bool) else str(value)

"""PX4 ULog, read by the vectorised reader in ulog_reader (same values as pyulog, the parser
PX4 Flight Review uses; bench/bench_logs.py times both on the same file).

`read` holds every topic in memory; `write` (what logs.store.import_to_store runs) writes
each block of records to the store's columns as the reader hands it over, so a log of any
size costs a chunk of the file and a block of records, not the log."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from logs.importers.base import Limits, LogFormatError, Progress, describe
from logs.importers.ulog_reader import (
    MAGIC,
    Dataset,
    Topic,
    UlogError,
    UlogFile,
    read_ulog,
    stream_ulog,
)
from logs.series import Kind, LogData, Series, join
from logs.units import ulog_unit

if TYPE_CHECKING:
    from logs.store import Column, Columns

LOG_LEVELS = {
    ord("0") + n: name
    for n, name in enumerate(
        ["emergency", "alert", "critical", "error", "warning", "notice", "info", "debug"]
    )
}

# Reader hints for the dedicated views: (topic, field) of instance 0 -> special key. PX4
# logs both the raw GPS and the estimator's fused position; the fused one is the track.
SPECIAL: dict[tuple[str, str], str | tuple[str, ...]] = {
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


@dataclass
class _Topic:
    """One topic instance's series: its times (ns), its fields and, for the attitude, the
    Euler angles derived from its quaternion."""

    name: str
    multi_id: int
    times: np.ndarray
    fields: dict[str, np.ndarray]
    euler: dict[str, np.ndarray] = field(default_factory=dict)


class UlogImporter:
    name = "PX4 ULog"
    extensions = (".ulg", ".ulog")

    def sniff(self, path: Path, head: bytes) -> bool:
        return head.startswith(MAGIC)

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        ulog = _parse(path, progress)
        return _log_data(ulog, [_in_memory(d) for d in ulog.data_list])

    def write(self, path: Path, columns: Columns, *, limits: Limits, progress: Progress) -> LogData:
        sink = _ColumnSink(columns)
        ulog = _parse(path, progress, sink)
        return _log_data(ulog, sink.topics())


def _parse(path: Path, progress: Progress, sink: _ColumnSink | None = None) -> UlogFile:
    def reading(fraction: float) -> None:
        progress(0.8 * fraction)

    try:
        return read_ulog(path, reading) if sink is None else stream_ulog(path, sink, reading)
    except UlogError as exc:
        raise LogFormatError(
            f"The file {path.name!r} is not a valid PX4 ULog: {describe(exc)}."
        ) from exc


def _parameters(ulog: UlogFile) -> dict:
    """The parameters at the start, each changed in flight at its last value: the rule
    every format's parameters follow (logs/parameters.py)."""
    values = dict(ulog.initial_parameters)
    values.update(ulog.changed_parameters)
    return values


def _log_data(ulog: UlogFile, topics: list[_Topic]) -> LogData:
    log = LogData(format="ulog")
    log.metadata = {
        "info": {k: _plain(v) for k, v in ulog.msg_info_dict.items()},
        "parameters": {k: _plain(v) for k, v in _parameters(ulog).items()},
        "start_timestamp_us": int(ulog.start_timestamp),
        # Data the logger could not write (the file's dropout messages), in ms.
        "dropouts_ms": int(ulog.dropouts_ms),
    }
    if ulog.file_corruption:
        log.warnings.append("The log has corrupt data; the readable messages were kept.")
    counts: dict[str, int] = {}
    for topic in topics:
        counts[topic.name] = counts.get(topic.name, 0) + 1
    for topic in topics:
        # A topic with several instances gets one layer per instance.
        layer = topic.name if counts[topic.name] == 1 else f"{topic.name}_{topic.multi_id}"
        _add_topic(log, layer, topic)
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


def _add_topic(log: LogData, layer: str, topic: _Topic) -> None:
    for name, values in topic.fields.items():
        special = SPECIAL.get((topic.name, name)) if topic.multi_id == 0 else None
        log.add(
            Series(
                join(layer, name),
                values,
                topic.times,
                unit=ulog_unit(topic.name, name),
                time_source="board",
                kind=_kind(values),
                special=special,
            )
        )
    # PX4 logs attitude only as a quaternion (w, x, y, z; body FRD to NED); the 3D view and
    # the trajectory want yaw, pitch, roll in that order (z, then y, then x).
    for name, values in topic.euler.items():
        log.add(
            Series(
                join(layer, "euler", name),
                values,
                topic.times,
                unit="rad",
                time_source="board",
                special=f"rotation.{name}",
            )
        )


def _has_euler(name: str, multi_id: int, fields: Collection[str]) -> bool:
    return name == "vehicle_attitude" and multi_id == 0 and "q[3]" in fields


def _in_memory(d: Dataset) -> _Topic:
    fields = {n: v for n, v in d.data.items() if n != "timestamp"}
    euler = _euler(d.data) if _has_euler(d.name, d.multi_id, d.data) else {}
    return _Topic(d.name, d.multi_id, _nanoseconds(d.data["timestamp"]), fields, euler)


@dataclass
class _Plan:
    """The columns a topic's blocks go to."""

    times: Column
    fields: dict[str, Column]
    euler: dict[str, Column]


class _ColumnSink:
    """The reader's records written to the store's columns a block at a time: times in ns,
    each field, the attitude's Euler angles. Holds one block of records."""

    def __init__(self, columns: Columns) -> None:
        self.columns = columns
        self.plans: dict[Topic, _Plan] = {}
        self.buffer = np.empty(0, dtype=np.uint8)

    def begin(self, log: UlogFile, topics: list[Topic]) -> None:
        create = self.columns.create
        for topic in topics:
            names = [n for n in topic.dtype.names or () if n != "timestamp"]
            _stamp_type(topic.dtype["timestamp"])
            euler = _has_euler(topic.name, topic.multi_id, names)
            self.plans[topic] = _Plan(
                create(np.int64, topic.count, times=True),
                {n: create(topic.dtype[n], topic.count) for n in names},
                {a: create(np.float32, topic.count) for a in EULER_ANGLES} if euler else {},
            )

    def rows(self, topic: Topic, at: int, count: int) -> np.ndarray:
        size = count * topic.dtype.itemsize
        if len(self.buffer) < size:
            self.buffer = np.empty(size, dtype=np.uint8)
        return self.buffer[:size].view(topic.dtype)

    def filled(self, topic: Topic, rows: np.ndarray) -> None:
        plan, append = self.plans[topic], self.columns.append
        times = np.ascontiguousarray(rows["timestamp"]).view(np.int64)
        append(plan.times, _nanoseconds(times))
        for name, column in plan.fields.items():
            append(column, rows[name])
        if plan.euler:
            for name, values in _euler(rows).items():
                append(plan.euler[name], values)

    def topics(self) -> list[_Topic]:
        load = self.columns.load
        return [
            _Topic(
                topic.name,
                topic.multi_id,
                load(plan.times),
                {n: load(c) for n, c in plan.fields.items()},
                {n: load(c) for n, c in plan.euler.items()},
            )
            for topic, plan in self.plans.items()
        ]


# Attitude rows converted at a time: the float64 working copies stay a few MiB however
# long the log.
EULER_BLOCK = 1 << 18


EULER_ANGLES = ("roll", "pitch", "yaw")


def _euler(data: dict | np.ndarray) -> dict[str, np.ndarray]:
    """Roll, pitch and yaw from the logged quaternion (`data[f"q[{i}]"]`), computed in
    float64 and kept in float32, the quaternion's own precision."""
    q = [data[f"q[{i}]"] for i in range(4)]
    angles = {name: np.empty(len(q[0]), dtype=np.float32) for name in EULER_ANGLES}
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
    _stamp_type(stamps.dtype)
    times = stamps.view(np.int64)
    np.multiply(times, 1000, out=times)
    return times


def _stamp_type(dtype: np.dtype) -> None:
    """A time stamp is 8 bytes (PX4's uint64 µs); any other would be read as something else."""
    if dtype.itemsize != 8:
        raise ValueError(f"a timestamp field of type {dtype} is not PX4's uint64")


def _kind(values: np.ndarray) -> Kind:
    return "double" if values.dtype.kind == "f" else "int"


def _plain(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return value if isinstance(value, int | float | str | bool) else str(value)

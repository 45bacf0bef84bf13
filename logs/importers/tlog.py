"""MAVLink telemetry logs (.tlog): each record is an 8-byte big-endian µs time stamp written
by the ground station (recorder time) followed by one MAVLink packet; decoded by pymavlink."""

from __future__ import annotations

from pathlib import Path
from typing import Any

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


# MAV_AUTOPILOT_INVALID (MAVLink common.xml): a HEARTBEAT from a component that is not a
# flight controller (a ground station, a gimbal, a companion computer).
AUTOPILOT_INVALID = 8

Sender = tuple[int, int]  # (system id, component id)


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
        senders = _Senders()
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
                senders.add(msg, kind)
                tick(conn.f.tell())
        finally:
            conn.close()
        if not senders.counts:
            raise LogFormatError(
                f"The file {path.name!r} holds no MAVLink messages: not a .tlog, or truncated."
            )
        log = LogData(format="tlog")
        if bad:
            log.warnings.append(f"Skipped {bad} corrupt MAVLink packets.")
        senders.columns().build(log, "recorder")
        return log


def _fields(msg: Any) -> dict[str, object]:
    """A message's numbers and texts by field name; an array field as name[i]."""
    fields: dict[str, object] = {}
    for name in msg.get_fieldnames():
        value = getattr(msg, name)
        if isinstance(value, list | tuple):
            for i, item in enumerate(value):
                if isinstance(item, int | float):
                    fields[f"{name}[{i}]"] = item
        elif isinstance(value, bytes | str):
            text = value.decode("utf-8", "replace") if isinstance(value, bytes) else value
            fields[name] = text.rstrip("\0")
        elif isinstance(value, int | float):
            fields[name] = value
    return fields


class _Senders:
    """Each message's columns kept apart by the component that sent it: a ground station
    records its own HEARTBEATs, and those of gimbals and companion computers, beside the
    vehicle's, and one series of them all would read as a vehicle changing its type and
    mode several times a second."""

    def __init__(self) -> None:
        self.cols = ColumnCollector()
        self.layers: dict[str, tuple[str, Sender]] = {}
        self.units: dict[str, dict[str, str]] = {}
        self.counts: dict[Sender, int] = {}
        self.autopilots: set[Sender] = set()

    def add(self, msg: Any, kind: str) -> None:
        sender = (msg.get_srcSystem(), msg.get_srcComponent())
        layer = f"{kind}[{sender[0]}:{sender[1]}]"
        self.layers.setdefault(layer, (kind, sender))
        self.cols.add(layer, round(msg._timestamp * 1e6) * 1000, _fields(msg))
        self.counts[sender] = self.counts.get(sender, 0) + 1
        if kind == "HEARTBEAT" and getattr(msg, "autopilot", None) != AUTOPILOT_INVALID:
            self.autopilots.add(sender)
        if kind not in self.units:
            units = getattr(msg, "fieldunits_by_name", None) or {}
            self.units[kind] = {name: unit for name, unit in units.items() if unit}

    def vehicle(self) -> Sender:
        """The flight controller: of the senders whose HEARTBEAT names an autopilot (else of
        all), the one that sent the most."""
        pool = self.autopilots or set(self.counts)
        return max(pool, key=lambda s: (self.counts[s], -s[0], -s[1]))

    def columns(self) -> ColumnCollector:
        """The vehicle's messages under their own names (HEARTBEAT), every other sender's
        with its system and component ids (HEARTBEAT[255:190])."""
        vehicle = self.vehicle()
        cols = self.cols
        named = {}
        for layer, columns in cols.layers.items():
            kind, sender = self.layers[layer]
            final = kind if sender == vehicle else layer
            named[final] = columns
            for name, unit in self.units[kind].items():
                cols.units[f"{final}/{name}"] = unit
        cols.layers = named
        cols.special.update(SPECIAL)  # the vehicle's own quantities: its layers' names
        return cols

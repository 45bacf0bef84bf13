"""ROS 1 bags through `rosbags`: every topic's numeric fields flattened into series, plus
the AR.Drone topics (ardrone_autonomy Navdata, cmd_vel) tagged as the special quantities
([Procházka 2016], §7.6.1)."""

from __future__ import annotations

import bz2
import io
from functools import partial
from pathlib import Path

import lz4.frame
import numpy as np
from rosbags.rosbag1 import Reader
from rosbags.rosbag1.reader import decompressors
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from logs.importers.base import Limits, LogFormatError, Progress, ProgressTicker, describe
from logs.importers.columns import ColumnCollector
from logs.series import LogData, join

MAGIC = b"#ROSBAG V2.0"
# A chunk may decompress to its compressed size times the limits' ratio, plus this much
# (a tiny chunk of a few messages compresses badly, never hugely).
CHUNK_SLACK_BYTES = 64 << 10
# Fixed-size arrays up to this length become one series per element; longer arrays and
# variable-length sequences (images, point clouds, tag lists) are not plottable quantities.
MAX_ARRAY = 16
NAVDATA_TYPE = "ardrone_autonomy/msg/Navdata"
# ardrone_autonomy Navdata fields (its README): units and special meaning.
NAVDATA = {
    "altd": ("mm", "altitude"),
    "vx": ("mm/s", "velocity.x"),
    "vy": ("mm/s", "velocity.y"),
    "vz": ("mm/s", "velocity.z"),
    "rotX": ("deg", "rotation.roll"),
    "rotY": ("deg", "rotation.pitch"),
    "rotZ": ("deg", "rotation.yaw"),
    "batteryPercent": ("%", "battery"),
    "motor1": ("", "motors.1"),
    "motor2": ("", "motors.2"),
    "motor3": ("", "motors.3"),
    "motor4": ("", "motors.4"),
    "ax": ("g", "acceleration.x"),
    "ay": ("g", "acceleration.y"),
    "az": ("g", "acceleration.z"),
    "magX": ("", "magnetometer.x"),
    "magY": ("", "magnetometer.y"),
    "magZ": ("", "magnetometer.z"),
    "tm": ("us", None),
    "pressure": ("Pa", None),
    "temp": ("", None),
}
NAVDATA_STATES = dict(
    enumerate(
        [
            "Unknown",
            "Inited",
            "Landed",
            "Flying",
            "Hovering",
            "Test",
            "Taking off",
            "Flying (go to fix point)",
            "Landing",
            "Looping",
        ]
    )
)


def flatten(msg: object, prefix: str, out: dict[str, object]) -> None:
    """Numeric and string leaves of a rosbags message dataclass, keyed by field path."""
    for name in getattr(msg, "__dataclass_fields__", {}):
        if name == "__msgtype__":
            continue
        value = getattr(msg, name)
        key = f"{prefix}/{name}" if prefix else name
        if isinstance(value, bool | int | float | np.integer | np.floating):
            out[key] = (
                value.item()
                if isinstance(value, np.generic)
                else (int(value) if isinstance(value, bool) else value)
            )
        elif isinstance(value, str):
            out[key] = value
        elif isinstance(value, np.ndarray):
            if value.ndim == 1 and 0 < len(value) <= MAX_ARRAY and value.dtype.kind in "iuf":
                for i, item in enumerate(value.tolist()):
                    out[f"{key}[{i}]"] = item
        elif hasattr(value, "__dataclass_fields__"):
            flatten(value, key, out)


class _FileOfSize(io.BufferedReader):
    """A bag file whose reads never ask for more than is left in it: the reader allocates
    what a length field claims before reading, and a corrupt one claims up to 4 GiB."""

    def __init__(self, path: Path) -> None:
        super().__init__(io.FileIO(path, "rb"))
        self.size = path.stat().st_size

    def read(self, size: int | None = -1) -> bytes:
        if size is not None and size > 0:
            size = max(min(size, self.size - self.tell()), 0)
        return super().read(size)


class _BagPath(type(Path())):  # type: ignore[misc]
    """The bag's path as the reader opens it: through _FileOfSize."""

    def open(self, *_args: object, **_kwargs: object) -> _FileOfSize:  # type: ignore[override]
        return _FileOfSize(Path(self))


class ChunkBudget:
    """Decompresses a bag's chunks within bounds, whatever their headers say: each chunk to
    at most `ratio` times its compressed bytes (plus CHUNK_SLACK_BYTES), and all chunks
    together, counting a chunk read again for messages out of order, to `total` bytes."""

    def __init__(self, name: str, *, ratio: float, total: int) -> None:
        self.name = name
        self.ratio = ratio
        self.left = total

    def install(self, reader: Reader) -> None:
        """Swap the reader's own decompressors (unbounded) for the capped ones."""
        kinds = {id(fn): kind for kind, fn in decompressors.items()}
        reader.chunks = {
            pos: chunk._replace(
                decompressor=partial(self.decompress, kinds[id(chunk.decompressor)])
            )
            for pos, chunk in reader.chunks.items()
        }

    def decompress(self, kind: str, data: bytes) -> bytes:
        cap = min(int(self.ratio * len(data)) + CHUNK_SLACK_BYTES, self.left)
        if kind == "bz2":
            out = bz2.BZ2Decompressor().decompress(data, max_length=cap + 1)
        elif kind == "lz4":
            out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=cap + 1)
        else:
            out = data
        if len(out) > cap:
            raise LogFormatError(
                f"The bag {self.name!r} decompresses past its limit ({cap} bytes for a chunk "
                f"of {len(data)}), so it was refused as a compression bomb."
            )
        self.left -= len(out)
        return out


def chunk_budget(path: Path, limits: Limits) -> ChunkBudget:
    """The ratio of the limits for each chunk; in all, the file's own size or its size times
    the ratio up to the limits' uncompressed ceiling, whichever is more."""
    size = path.stat().st_size
    ratio = limits.max_compression_ratio
    total = max(size, min(int(ratio * size), limits.max_uncompressed_bytes))
    return ChunkBudget(path.name, ratio=ratio, total=total)


class RosbagImporter:
    name = "ROS 1 bag"
    extensions = (".bag",)

    def sniff(self, path: Path, head: bytes) -> bool:
        return head.startswith(MAGIC)

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        typestore = get_typestore(Stores.ROS1_NOETIC)
        cols = ColumnCollector()
        log = LogData(format="rosbag")
        try:
            reader = Reader(_BagPath(path))
            reader.open()
            chunk_budget(path, limits).install(reader)
        except Exception as exc:
            raise LogFormatError(
                f"The file {path.name!r} is not a readable ROS 1 bag (truncated?): {describe(exc)}."
            ) from exc
        undecodable: dict[str, int] = {}
        try:
            for conn in reader.connections:
                # Bags carry each message definition: register types the store lacks
                # (ardrone_autonomy/Navdata and any custom message).
                if conn.msgtype not in typestore.fielddefs:
                    try:
                        typestore.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
                    except Exception:
                        undecodable[conn.topic] = 0
            tick = ProgressTicker(progress, max(reader.message_count, 1))
            for done, (conn, bag_ns, raw) in enumerate(reader.messages()):
                tick(done)
                if conn.topic in undecodable:
                    undecodable[conn.topic] += 1
                    continue
                try:
                    msg = typestore.deserialize_ros1(raw, conn.msgtype)
                except Exception:
                    undecodable[conn.topic] = undecodable.get(conn.topic, 0) + 1
                    continue
                fields: dict[str, object] = {}
                flatten(msg, "", fields)
                layer = join(conn.topic.strip("/"))
                cols.add(layer, bag_ns, fields)
                if conn.msgtype == NAVDATA_TYPE and f"{layer}/state" not in cols.labels:
                    self._tag_navdata(cols, layer)
        finally:
            reader.close()
        for topic, count in undecodable.items():
            log.warnings.append(f"Topic {topic}: {count} messages could not be decoded.")
        if not cols.layers:
            raise LogFormatError(f"The bag {path.name!r} holds no messages we can decode.")
        # Bag time stamps are taken by the recording machine on receipt.
        cols.build(log, "recorder")
        return log

    @staticmethod
    def _tag_navdata(cols: ColumnCollector, layer: str) -> None:
        cols.labels[f"{layer}/state"] = NAVDATA_STATES
        for name, (unit, special) in NAVDATA.items():
            if unit:
                cols.units[f"{layer}/{name}"] = unit
            if special:
                cols.special[f"{layer}/{name}"] = special

"""ArduPilot DataFlash .bin logs: a vectorised reader over the FMT-described records.

One pass in Python only finds record starts (0xA3 0x95 + type, length from FMT) and
follows FMT records; every field of every message type is then decoded at once with a
numpy structured dtype over the gathered record bytes. pymavlink instead builds one Python
object per record, which is what makes it slow on 100 MB logs.
"""

from __future__ import annotations

import math
import mmap
from array import array
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from logs.importers.base import Limits, LogFormatError, Progress, ProgressTicker
from logs.series import LogData, Series, join

HEAD = b"\xa3\x95"
# Sensors of one kind on a vehicle (ArduPilot has at most a few IMUs, GPSs, batteries).
MAX_INSTANCES = 16
FMT_TYPE = 0x80
FMT_LEN = 89
# Format characters (ArduPilot AP_Logger / pymavlink DFReader.FORMAT_TO_STRUCT): dtype and
# scale; a scaled integer becomes float64 like pymavlink's value.
FORMAT_CHARS: dict[str, tuple[str, float | None]] = {
    "a": ("(32,)<i2", None),
    "b": ("i1", None),
    "B": ("u1", None),
    "g": ("<f2", None),
    "h": ("<i2", None),
    "H": ("<u2", None),
    "i": ("<i4", None),
    "I": ("<u4", None),
    "f": ("<f4", None),
    "d": ("<f8", None),
    "n": ("S4", None),
    "N": ("S16", None),
    "Z": ("S64", None),
    "c": ("<i2", 0.01),
    "C": ("<u2", 0.01),
    "e": ("<i4", 0.01),
    "E": ("<u4", 0.01),
    "L": ("<i4", 1e-7),
    "M": ("i1", None),
    "q": ("<i8", None),
    "Q": ("<u8", None),
}
# Reader hints for the dedicated views (find_special): (message, field) -> special key.
SPECIAL = {
    ("ATT", "Roll"): "rotation.roll",
    ("ATT", "Pitch"): "rotation.pitch",
    ("ATT", "Yaw"): "rotation.yaw",
    ("GPS", "Lat"): "gps.lat",
    ("GPS", "Lng"): "gps.lon",
    ("GPS", "Alt"): "gps.alt",
    ("CTUN", "Alt"): "altitude",
    ("IMU", "AccX"): "acceleration.x",
    ("IMU", "AccY"): "acceleration.y",
    ("IMU", "AccZ"): "acceleration.z",
    ("MAG", "MagX"): "magnetometer.x",
    ("MAG", "MagY"): "magnetometer.y",
    ("MAG", "MagZ"): "magnetometer.z",
    ("BAT", "RemPct"): "battery",
    ("RCOU", "C1"): "motors.C1",
    ("RCOU", "C2"): "motors.C2",
    ("RCOU", "C3"): "motors.C3",
    ("RCOU", "C4"): "motors.C4",
}


class Format:
    def __init__(self, type_: int, length: int, name: str, chars: str, columns: list[str]) -> None:
        self.type = type_
        self.length = length
        self.name = name
        self.chars = chars
        self.columns = columns
        fields = []
        self.scales: dict[str, float] = {}
        self.multipliers: dict[str, float] = {}  # from FMTU/MULT, for unscaled columns
        for char, col in zip(chars, columns, strict=False):
            if char not in FORMAT_CHARS:
                raise LogFormatError(f"FMT of {name}: unsupported format character {char!r}.")
            dtype, scale = FORMAT_CHARS[char]
            fields.append((col, dtype))
            if scale:
                self.scales[col] = scale
        self.dtype = np.dtype(fields) if fields else None
        if self.dtype is not None and self.dtype.itemsize != length - 3:
            raise LogFormatError(
                f"FMT of {name}: format {chars!r} is {self.dtype.itemsize} bytes, but the record is {length - 3}."
            )


def _text(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("utf-8", "replace")


def _parse_fmt(record: bytes) -> Format:
    type_, length = record[3], record[4]
    name = _text(record[5:9])
    chars = _text(record[9:25])
    columns = [c for c in _text(record[25:89]).split(",") if c]
    if len(columns) != len(chars):
        raise LogFormatError(
            f"FMT of {name}: {len(chars)} format characters but {len(columns)} columns."
        )
    return Format(type_, length, name, chars, columns)


@dataclass
class Scan:
    formats: dict[int, Format]
    offsets: dict[int, array]  # record starts per message type (int64)
    skipped: int  # bytes of corrupt or unknown records
    truncated: bool  # the last record is cut short
    bad_formats: list[str]  # FMT records that could not be used


def scan(data: bytes | mmap.mmap, progress: Progress) -> Scan:
    """Find every record start, following FMT records as they come."""
    bad_formats: list[str] = []
    lengths = [0] * 256
    lengths[FMT_TYPE] = FMT_LEN
    formats: dict[int, Format] = {}
    # array('q') holds 8 bytes per record where a list of ints holds 36: a 1 GB log has
    # tens of millions of records.
    offsets: dict[int, array] = {}
    appenders = [None] * 256
    n = len(data)
    pos = 0
    skipped = 0
    truncated = False
    tick = ProgressTicker(lambda f: progress(0.6 * f), n)
    find = data.find
    counter = 0
    while pos + 3 <= n:
        if data[pos] == 0xA3 and data[pos + 1] == 0x95:
            t = data[pos + 2]
            length = lengths[t]
            if length:
                if pos + length > n:
                    truncated = True
                    break
                append = appenders[t]
                if append is None:
                    append = appenders[t] = offsets.setdefault(t, array("q")).append
                append(pos)
                if t == FMT_TYPE:
                    try:
                        fmt = _parse_fmt(bytes(data[pos : pos + FMT_LEN]))
                    except LogFormatError as exc:
                        # Losing one message type beats losing the flight.
                        bad_formats.append(str(exc))
                    else:
                        if fmt.type != FMT_TYPE:
                            formats[fmt.type] = fmt
                            lengths[fmt.type] = fmt.length
                pos += length
                counter += 1
                if counter & 0xFFFF == 0:
                    tick(pos)
                continue
        # Corrupt or unknown bytes: resynchronise on the next header (pymavlink does the same).
        nxt = find(HEAD, pos + 1)
        if nxt < 0:
            if n - pos >= 3:
                skipped += n - pos
            else:
                truncated = True
            break
        skipped += nxt - pos
        pos = nxt
    return Scan(formats, offsets, skipped, truncated, bad_formats)


def _no_formats(path: Path, bad_formats: list[str]) -> str:
    """Why a log has no message type to read: no FMT record, or none usable (and why)."""
    if not bad_formats:
        return f"The file {path.name!r} has no FMT records: not a DataFlash log, or truncated."
    more = f" (and {len(bad_formats) - 1} more)" if len(bad_formats) > 1 else ""
    return (
        f"The file {path.name!r} has no FMT record we can use: {bad_formats[0].rstrip('.')}{more}."
    )


class DataFlashImporter:
    name = "ArduPilot DataFlash"
    extensions = (".bin",)

    def sniff(self, path: Path, head: bytes) -> bool:
        # Every DataFlash log opens with the FMT record that describes FMT itself.
        return head[:4] == HEAD + bytes([FMT_TYPE, FMT_TYPE])

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        with path.open("rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            found = scan(data, progress)
            formats, offsets = found.formats, found.offsets
            if not formats:
                raise LogFormatError(_no_formats(path, found.bad_formats))
            buf = np.frombuffer(data, dtype=np.uint8)
            log = LogData(format="dataflash")
            if found.skipped:
                log.warnings.append(f"Skipped {found.skipped} bytes of corrupt or unknown records.")
            log.warnings.extend(f"Ignored a corrupt FMT record: {m}" for m in found.bad_formats)
            if found.truncated:
                log.warnings.append("The last record is truncated and was dropped.")
            try:
                self._decode(buf, formats, offsets, log, progress)
            finally:
                del buf  # the mmap cannot close while a numpy view exports its buffer
        return log

    def _decode(
        self,
        buf: np.ndarray,
        formats: dict[int, Format],
        offsets: dict[int, array],
        log: LogData,
        progress: Progress,
    ) -> None:
        decoded: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for number, (t, offs) in enumerate(offsets.items()):
            fmt = formats.get(t)
            if t == FMT_TYPE or fmt is None or fmt.dtype is None:
                continue
            starts = np.frombuffer(offs, dtype=np.int64) + 3
            body = fmt.length - 3
            windows = np.lib.stride_tricks.sliding_window_view(buf, body)
            records = np.ascontiguousarray(windows[starts]).view(fmt.dtype).reshape(-1)
            decoded[t] = (starts, records)
            progress(0.6 + 0.3 * (number + 1) / len(offsets))
        inherited = _inherited_times(decoded)
        units, instances = _units_and_instances(formats, decoded)
        multipliers = _multipliers(formats, decoded)
        for t, (starts, records) in decoded.items():
            fmt = formats[t]
            times = _times_ns(records)
            if times is None:
                times = inherited(starts)
            column_units = units.get(fmt.name, {})
            fmt.multipliers = multipliers.get(fmt.name, {})
            instance = instances.get(fmt.name)
            values_seen = np.unique(records[instance]) if instance else []
            if len(values_seen) > MAX_INSTANCES:
                # A layer per instance would make series by the record, not by the sensor.
                log.warnings.append(
                    f"{fmt.name}: {len(values_seen)} instances, over {MAX_INSTANCES}; kept as one."
                )
                values_seen = []
            if len(values_seen) > 1:
                # Several sensors of one kind (IMU, GPS, BARO...) log under one message
                # name; one layer per instance, named as pymavlink does: IMU[0], IMU[1].
                for number, value in enumerate(values_seen.tolist()):
                    mask = records[instance] == value
                    self._emit(
                        log,
                        fmt,
                        f"{fmt.name}[{value}]",
                        records[mask],
                        times[mask],
                        column_units,
                        number == 0,
                    )
            else:
                self._emit(log, fmt, fmt.name, records, times, column_units, True)

    @staticmethod
    def _emit(
        log: LogData,
        fmt: Format,
        layer: str,
        records: np.ndarray,
        times: np.ndarray,
        units: dict[str, str],
        hinted: bool,
    ) -> None:
        for col in fmt.columns:
            if col in ("TimeUS", "TimeMS"):
                continue
            values = records[col]
            if values.dtype.kind == "S":
                values = np.array([_text(v) for v in values.tolist()], dtype=str)
                kind = "text"
            elif col in fmt.scales:
                values = values.astype(np.float64) * fmt.scales[col]
                kind = "double"
            elif col in fmt.multipliers and values.ndim == 1:
                # FMTU's multiplier: stored number x multiplier = value in the column's unit.
                values = values.astype(np.float64) * fmt.multipliers[col]
                kind = "double"
            elif values.ndim > 1:
                for i in range(values.shape[1]):
                    log.add(
                        Series(
                            join(layer, f"{col}[{i}]"),
                            values[:, i].copy(),
                            times,
                            time_source="board",
                            kind="int",
                        )
                    )
                continue
            else:
                values = values.copy()  # own the memory so the file's mmap can close
                kind = "double" if values.dtype.kind == "f" else "int"
            log.add(
                Series(
                    join(layer, col),
                    values,
                    times,
                    unit=units.get(col, ""),
                    time_source="board",
                    kind=kind,  # type: ignore[arg-type]
                    special=SPECIAL.get((fmt.name, col)) if hinted else None,
                )
            )


def _units_and_instances(
    formats: dict[int, Format], decoded: dict[int, tuple[np.ndarray, np.ndarray]]
) -> tuple[dict[str, dict[str, str]], dict[str, str]]:
    """Column units and instance columns from the UNIT and FMTU messages (ArduPilot 3.6+):
    FMTU gives one unit id character per column, '#' marking the instance column."""
    by_name = {formats[t].name: records for t, (_, records) in decoded.items()}
    labels: dict[str, str] = {}
    unit_records = by_name.get("UNIT")
    if unit_records is not None and {"Id", "Label"} <= set(unit_records.dtype.names or ()):
        for uid, label in zip(
            unit_records["Id"].tolist(), unit_records["Label"].tolist(), strict=True
        ):
            labels[chr(uid & 0xFF)] = _text(label)
    units: dict[str, dict[str, str]] = {}
    instances: dict[str, str] = {}
    fmtu = by_name.get("FMTU")
    if fmtu is None or not {"FmtType", "UnitIds"} <= set(fmtu.dtype.names or ()):
        return units, instances
    for ftype, ids in zip(fmtu["FmtType"].tolist(), fmtu["UnitIds"].tolist(), strict=True):
        fmt = formats.get(ftype)
        if fmt is None:
            continue
        ids_text = _text(ids)
        units[fmt.name] = {
            col: labels[uid]
            for col, uid in zip(fmt.columns, ids_text, strict=False)
            if uid in labels
        }
        if "#" in ids_text and ids_text.index("#") < len(fmt.columns):
            instances[fmt.name] = fmt.columns[ids_text.index("#")]
    return units, instances


def _multipliers(
    formats: dict[int, Format], decoded: dict[int, tuple[np.ndarray, np.ndarray]]
) -> dict[str, dict[str, float]]:
    """Per message, the multiplier of each column from FMTU's MultIds and the MULT messages,
    for columns whose format character does not scale them already (c, C, e, E, L do, and
    ArduPilot names the same factor in FMTU for them). No multiplier (0, '-') or 1 is left out."""
    by_name = {formats[t].name: records for t, (_, records) in decoded.items()}
    mult, fmtu = by_name.get("MULT"), by_name.get("FMTU")
    if mult is None or fmtu is None or not {"Id", "Mult"} <= set(mult.dtype.names or ()):
        return {}
    if "MultIds" not in (fmtu.dtype.names or ()):
        return {}
    factors = {
        chr(i & 0xFF): float(m)
        for i, m in zip(mult["Id"].tolist(), mult["Mult"].tolist(), strict=True)
    }
    out: dict[str, dict[str, float]] = {}
    for ftype, ids in zip(fmtu["FmtType"].tolist(), fmtu["MultIds"].tolist(), strict=True):
        fmt = formats.get(ftype)
        if fmt is None:
            continue
        out[fmt.name] = {
            col: factors[mid]
            for col, mid in zip(fmt.columns, _text(ids), strict=False)
            if col not in fmt.scales
            and col not in ("TimeUS", "TimeMS")
            and math.isfinite(factors.get(mid, 0.0))
            and factors.get(mid, 0.0) not in (0.0, 1.0)
        }
    return out


def _times_ns(records: np.ndarray) -> np.ndarray | None:
    names = records.dtype.names or ()
    if "TimeUS" in names:
        return records["TimeUS"].astype(np.int64) * 1000
    if "TimeMS" in names:
        return records["TimeMS"].astype(np.int64) * 1_000_000
    return None


def _inherited_times(
    decoded: dict[int, tuple[np.ndarray, np.ndarray]],
) -> Callable[[np.ndarray], np.ndarray]:
    """Records without a time field take the time of the last timed record before them
    (by file offset); with no timed record at all, zero."""
    timed_offs, timed_ns = [], []
    for starts, records in decoded.values():
        ns = _times_ns(records)
        if ns is not None:
            timed_offs.append(starts)
            timed_ns.append(ns)
    if not timed_offs or not sum(len(offs) for offs in timed_offs):
        return lambda starts: np.zeros(len(starts), dtype=np.int64)
    all_offs = np.concatenate(timed_offs)
    order = np.argsort(all_offs, kind="stable")
    all_offs, all_ns = all_offs[order], np.concatenate(timed_ns)[order]
    return lambda starts: all_ns[np.maximum(np.searchsorted(all_offs, starts, side="right") - 1, 0)]

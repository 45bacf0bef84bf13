"""Columnar storage of a parsed log: one .npy per time array and per value array, plus
index.json, read back memory-mapped by path and time range.

Layout of a store directory:
    index.json   format, layers, series (unit, kind, count, start, end, time source,
                 enumeration labels, file names), special quantities, metadata, warnings
    t<k>.npy     int64 nanoseconds; written once per distinct time array (a message's
                 fields share one)
    v<k>.npy     values (int64, float, or unicode for text series)
    c<k>.npy     times or values written while the log was parsed (Columns), by an
                 importer that streams; the index names them like the others

Writes go to a hidden sibling directory that is renamed into place, so a reader never
sees a half-written store and a failed import leaves nothing behind.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from logs.importers import import_log
from logs.importers.base import DEFAULT_LIMITS, Limits, Progress, StoreWriteError, no_progress
from logs.lod import downsample
from logs.series import LogData, find_special

VERSION = 1
NS = 1_000_000_000


def _seconds(ns: int) -> float:
    return ns / NS


def write_store(log: LogData, directory: str | Path) -> dict:
    """Write `log` to `directory` atomically (replacing an older store there); returns the index."""
    return _replace(Path(directory), lambda out: _write(log, out))


def _replace(directory: Path, fill: Callable[[Path], dict]) -> dict:
    """`fill` writes a store into an empty hidden directory, which then replaces `directory`;
    when it raises, nothing is left behind and an older store stays."""
    directory.parent.mkdir(parents=True, exist_ok=True)
    tmp = directory.parent / f".{directory.name}.tmp-{uuid.uuid4().hex}"
    tmp.mkdir()
    try:
        index = fill(tmp)
        old = None
        if directory.exists():
            old = directory.parent / f".{directory.name}.old-{uuid.uuid4().hex}"
            os.rename(directory, old)
        os.rename(tmp, directory)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return index


@dataclass
class Column:
    """One .npy file of a store being written: `count` rows of `dtype`, `filled` so far.
    A column of times keeps its smallest and largest value as they come."""

    name: str
    dtype: np.dtype
    count: int
    times: bool = False
    filled: int = 0
    low: int | None = None
    high: int | None = None


class Columns:
    """The array files of a store being written while its log is parsed, for an importer
    that streams (logs.importers.base.StreamingImporter). A column's .npy header, row count
    included, is written when it is made and its rows are appended in order, a block at a
    time, so no series is ever held whole; `load` maps a complete column back read-only, and
    the store's index then names that file instead of saving the array again."""

    # Files kept open between appends; past this many, all are closed and reopened as needed.
    MAX_OPEN = 256

    def __init__(self, out: Path) -> None:
        self.out = out
        self.columns: list[Column] = []
        # The arrays `load` returned, by id (each kept, so that no other array takes its id).
        self.saved: dict[int, tuple[np.ndarray, Column]] = {}
        self._open: dict[str, IO[bytes]] = {}

    def create(self, dtype: np.dtype | type, count: int, *, times: bool = False) -> Column:
        column = Column(f"c{len(self.columns)}.npy", np.dtype(dtype), count, times)
        header = {
            "descr": np.lib.format.dtype_to_descr(column.dtype),
            "fortran_order": False,
            "shape": (count,),
        }
        with self._io():
            np.lib.format.write_array_header_1_0(self._file(column, "wb"), header)
        self.columns.append(column)
        return column

    def append(self, column: Column, values: np.ndarray) -> None:
        """The next rows of `column` (cast to its dtype)."""
        if column.filled + len(values) > column.count:
            raise ValueError(f"{column.name}: more than its {column.count} rows")
        values = np.ascontiguousarray(values, dtype=column.dtype)
        if column.times and len(values):
            low, high = int(values.min()), int(values.max())
            column.low = low if column.low is None else min(column.low, low)
            column.high = high if column.high is None else max(column.high, high)
        with self._io():
            self._file(column, "ab").write(values.data.cast("B"))
        column.filled += len(values)

    def load(self, column: Column) -> np.ndarray:
        """A complete column, memory-mapped read-only."""
        if column.filled != column.count:
            raise ValueError(f"{column.name}: {column.filled} of its {column.count} rows")
        with self._io():
            handle = self._open.pop(column.name, None)
            if handle is not None:
                handle.close()
            array = np.load(self.out / column.name, mmap_mode="r", allow_pickle=False)
        self.saved[id(array)] = (array, column)
        return array

    def close(self) -> None:
        for handle in self._open.values():
            handle.close()
        self._open.clear()

    def _file(self, column: Column, mode: str) -> IO[bytes]:
        handle = self._open.get(column.name)
        if handle is None:
            if len(self._open) >= self.MAX_OPEN:
                self.close()
            handle = self._open[column.name] = open(self.out / column.name, mode)  # noqa: SIM115
        return handle

    @staticmethod
    @contextmanager
    def _io() -> Iterator[None]:
        """A failed write (a full disk) is the server's trouble, not the log's."""
        try:
            yield
        except OSError as exc:
            raise StoreWriteError(f"writing the store failed: {exc}") from exc


def _write(log: LogData, out: Path, columns: Columns | None = None) -> dict:
    saved = columns.saved if columns is not None else {}
    time_files: dict[int, str] = {}
    series: dict[str, dict] = {}
    layers: dict[str, dict] = {}
    for number, s in enumerate(log):
        tname = time_files.get(id(s.times))
        if tname is None:
            tname = time_files[id(s.times)] = _save(
                out, s.times, f"t{len(time_files)}.npy", saved, np.int64
            )
        vname = _save(out, s.values, f"v{number}.npy", saved)
        start, end = _span(s.times, saved)
        series[s.path] = {
            "unit": s.unit,
            "kind": s.kind,
            "count": len(s.values),
            "start": start,
            "end": end,
            "time_source": s.time_source,
            "labels": {str(k): v for k, v in s.labels.items()} if s.labels else None,
            "times": tname,
            "values": vname,
        }
        layer = layers.setdefault(
            s.layer,
            {"name": s.layer, "time_source": s.time_source, "start": start, "end": end, "count": 0},
        )
        layer["count"] = max(layer["count"], len(s.values))
        if start is not None:
            layer["start"] = start if layer["start"] is None else min(layer["start"], start)
            layer["end"] = end if layer["end"] is None else max(layer["end"], end)
    starts = [x["start"] for x in layers.values() if x["start"] is not None]
    ends = [x["end"] for x in layers.values() if x["end"] is not None]
    index = {
        "version": VERSION,
        "format": log.format,
        "start": min(starts) if starts else None,
        "end": max(ends) if ends else None,
        "layers": list(layers.values()),
        "series": series,
        "special": find_special(log),
        "special_by_layer": log.special_by_layer(),
        "metadata": log.metadata,
        "warnings": log.warnings,
    }
    text = json.dumps(index, default=str, allow_nan=False)
    with open(out / "index.json", "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    return json.loads(text)


def _save(out: Path, array: np.ndarray, name: str, saved: dict, dtype: type | None = None) -> str:
    """The file of `array` in `out`: the column it was loaded from, or `name`, saved now."""
    known = saved.get(id(array))
    if known is not None:
        return known[1].name
    np.save(out / name, np.ascontiguousarray(array, dtype=dtype), allow_pickle=False)
    return name


def _span(times: np.ndarray, saved: dict) -> tuple[float | None, float | None]:
    """First and last time in seconds; a column of times knows them without being read."""
    if not len(times):
        return None, None
    known = saved.get(id(times))
    if known is not None and known[1].low is not None:
        return _seconds(known[1].low), _seconds(known[1].high)
    return _seconds(int(times.min())), _seconds(int(times.max()))


class LogStore:
    """A written store, read lazily: arrays are memory-mapped, never loaded whole."""

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        with open(self.directory / "index.json") as f:
            self.index: dict = json.load(f)
        if self.index.get("version") != VERSION:
            raise ValueError(f"store version {self.index.get('version')} is not {VERSION}")

    @property
    def paths(self) -> list[str]:
        return list(self.index["series"])

    @property
    def special(self) -> dict[str, list[str]]:
        return self.index["special"]

    @property
    def special_by_layer(self) -> dict[str, dict[str, list[str]]]:
        return self.index["special_by_layer"]

    def series_list(self) -> list[dict]:
        """The API's series summary: [{"path", "unit", "count", "start", "end"}] (seconds)."""
        return [
            {
                "path": p,
                "unit": i["unit"],
                "count": i["count"],
                "start": i["start"],
                "end": i["end"],
            }
            for p, i in self.index["series"].items()
        ]

    def info(self, path: str) -> dict:
        try:
            return self.index["series"][path]
        except KeyError:
            raise KeyError(f"no series {path!r} in this log") from None

    def _load(self, name: str) -> np.ndarray:
        # mmap_mode='r' maps the file: a range read touches only the pages it needs.
        return np.load(self.directory / name, mmap_mode="r", allow_pickle=False)

    def read_ns(
        self, path: str, start_ns: int | None = None, end_ns: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Samples with start_ns <= t <= end_ns (read-only memory maps; times in ns)."""
        info = self.info(path)
        t = self._load(info["times"])
        v = self._load(info["values"])
        lo = 0 if start_ns is None else int(np.searchsorted(t, start_ns, side="left"))
        hi = len(t) if end_ns is None else int(np.searchsorted(t, end_ns, side="right"))
        return t[lo:hi], v[lo:hi]

    def read(
        self, path: str, start: float | None = None, end: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Samples with start <= t <= end, times as float seconds."""
        t, v = self.read_ns(
            path,
            None if start is None else math.floor(start * NS),
            None if end is None else math.ceil(end * NS),
        )
        return t / NS, np.asarray(v)

    def plot(
        self,
        path: str,
        *,
        start: float | None = None,
        end: float | None = None,
        points: int | None = None,
    ) -> dict[str, list]:
        """The API's `{"t": [seconds], "v": [values]}`: all points in the range, or min/max
        downsampled to `points` pixel buckets. Non-finite values become null."""
        t_ns, v = self.read_ns(
            path,
            None if start is None else math.floor(start * NS),
            None if end is None else math.ceil(end * NS),
        )
        if points is not None:
            t_ns, v = downsample(t_ns, v, points)
        values = np.asarray(v)
        out_v = values.tolist()
        if values.dtype.kind == "f" and not np.isfinite(values).all():
            out_v = [x if math.isfinite(x) else None for x in out_v]
        return {"t": (np.asarray(t_ns) / NS).tolist(), "v": out_v}


def open_store(directory: str | Path) -> LogStore:
    """Open a store written by write_store."""
    return LogStore(directory)


def import_to_store(
    path: str | Path,
    directory: str | Path,
    *,
    limits: Limits = DEFAULT_LIMITS,
    progress: Progress = no_progress,
) -> LogStore:
    """What the import task runs: parse any supported log and store it atomically.
    Raises LogFormatError (nothing written) when the file cannot be read.

    An importer that streams writes its arrays into the store as it parses them, so the
    log is never held in memory whole; any other is read whole, then written."""

    def fill(out: Path) -> dict:
        columns = Columns(out)
        try:
            log = import_log(
                path, limits=limits, progress=lambda f: progress(0.9 * f), columns=columns
            )
            return _write(log, out, columns)
        finally:
            columns.close()

    _replace(Path(directory), fill)
    progress(1.0)
    return open_store(directory)

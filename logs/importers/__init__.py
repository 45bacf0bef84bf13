"""Importer registry: a new format is one module plus one line in REGISTRY."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from logs.importers.base import (
    DEFAULT_LIMITS,
    Importer,
    Limits,
    LogFormatError,
    Progress,
    StoreWriteError,
    describe,
    no_progress,
)
from logs.importers.dataflash import DataFlashImporter
from logs.importers.dfi import DfiImporter
from logs.importers.mission import MissionLogImporter
from logs.importers.rosbag import RosbagImporter
from logs.importers.tlog import TlogImporter
from logs.importers.ulog import UlogImporter
from logs.series import LogData

if TYPE_CHECKING:
    from logs.store import Columns

# Order matters only for sniffing: formats with strong magic bytes first.
REGISTRY: list[Importer] = [
    UlogImporter(),
    RosbagImporter(),
    DfiImporter(),
    DataFlashImporter(),
    MissionLogImporter(),
    TlogImporter(),
]

HEAD_BYTES = 4096


def pick_importer(path: Path, head: bytes) -> Importer:
    """By content first (magic bytes), by extension second."""
    for importer in REGISTRY:
        if importer.sniff(path, head):
            return importer
    suffix = path.suffix.lower()
    for importer in REGISTRY:
        if suffix in importer.extensions:
            return importer
    known = ", ".join(sorted({e for i in REGISTRY for e in i.extensions}))
    raise LogFormatError(
        f"The file {path.name!r} is not a flight log format we can read (supported: {known})."
    )


def import_log(
    path: str | Path,
    *,
    limits: Limits = DEFAULT_LIMITS,
    progress: Progress = no_progress,
    columns: Columns | None = None,
) -> LogData:
    """Read any supported flight log into the common data model.

    With `columns` (a store being written, logs.store.import_to_store), an importer that
    streams (base.StreamingImporter) writes its series there as it parses, and the result
    holds them memory-mapped; any other reads the whole file as without.

    Raises LogFormatError with a user-facing sentence for unknown, oversized, truncated or
    corrupt files; never anything else for bad input.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        with path.open("rb") as f:
            head = f.read(HEAD_BYTES)
    except OSError as exc:
        raise LogFormatError(f"The file {path.name!r} cannot be opened: {exc.strerror}.") from exc
    if size == 0:
        raise LogFormatError(f"The file {path.name!r} is empty.")
    if size > limits.max_file_bytes:
        raise LogFormatError(
            f"The file {path.name!r} is {size} bytes, over the limit of {limits.max_file_bytes}."
        )
    importer = pick_importer(path, head)
    write = getattr(importer, "write", None) if columns is not None else None
    try:
        if write is not None:
            log = write(path, columns, limits=limits, progress=progress)
        else:
            log = importer.read(path, limits=limits, progress=progress)
    except (LogFormatError, MemoryError, StoreWriteError):
        raise
    except Exception as exc:
        # Library readers (pyulog, pymavlink, rosbags) raise assorted errors on corrupt
        # input; whatever they raise, the worker must get one clear error and survive.
        raise LogFormatError(
            f"The file {path.name!r} is not a valid {importer.name} log: {describe(exc)}."
        ) from exc
    if not log.series:
        raise LogFormatError(f"The file {path.name!r} contains no data we can show.")
    progress(1.0)
    return log


__all__ = ["REGISTRY", "Importer", "Limits", "LogFormatError", "import_log", "pick_importer"]

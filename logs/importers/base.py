"""The importer interface every log format implements, and the errors and limits it shares."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from logs.series import LogData

if TYPE_CHECKING:
    from logs.store import Columns

Progress = Callable[[float], None]


class LogFormatError(Exception):
    """The file is not a log we can read; the message is one sentence for the user."""


class StoreWriteError(Exception):
    """Writing a parsed log to its store failed (a full disk): the server's trouble, never
    reported as the file's."""


@dataclass(frozen=True)
class Limits:
    """Ceilings that protect the worker from hostile or gigantic input."""

    max_file_bytes: int = 4 << 30
    # ZIP archives (DFI): total uncompressed size, per-member ratio, member count.
    max_uncompressed_bytes: int = 2 << 30
    max_compression_ratio: float = 200.0
    max_members: int = 1000
    max_xml_bytes: int = 16 << 20
    max_json_bytes: int = 512 << 20


DEFAULT_LIMITS = Limits()


class Importer(Protocol):
    """One log format. Register an instance in `logs.importers.REGISTRY`."""

    name: str
    extensions: tuple[str, ...]

    def sniff(self, path: Path, head: bytes) -> bool:
        """True when `head` (the first bytes of the file) carries this format's magic."""
        ...

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        """Parse the whole file; raise LogFormatError with a clear sentence if it is bad."""
        ...


class StreamingImporter(Importer, Protocol):
    """A format whose logs can be too large to hold: `write` parses like `read` but writes
    each series' times and values into `columns` (a store being written) as they are
    decoded, and the LogData it returns holds them mapped back from there
    (logs.store.Columns.load). logs.store.import_to_store uses it when present."""

    def write(self, path: Path, columns: Columns, *, limits: Limits, progress: Progress) -> LogData:
        """Parse the whole file into `columns`; raise LogFormatError if it is bad."""
        ...


def no_progress(_fraction: float) -> None:
    """Default progress callback."""


class ProgressTicker:
    """Calls `progress` at most every 1 % so a tight loop stays cheap."""

    def __init__(self, progress: Progress, total: int) -> None:
        self._progress = progress
        self._step = max(total // 100, 1)
        self._total = max(total, 1)
        self._next = 0

    def __call__(self, done: int) -> None:
        if done >= self._next:
            self._next = done + self._step
            self._progress(min(done / self._total, 1.0))


def describe(exc: BaseException) -> str:
    """An exception as the tail of one of our sentences (no doubled full stop)."""
    return str(exc).strip().rstrip(".") or type(exc).__name__

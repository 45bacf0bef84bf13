"""The importer interface every log format implements, and the errors and limits it shares."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from logs.series import LogData

Progress = Callable[[float], None]


class LogFormatError(Exception):
    """The file is not a log we can read; the message is one sentence for the user."""


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

"""The flight controller's own log of a flight, fetched over MAVLink's log protocol
[MAVLink common: LOG_REQUEST_LIST, LOG_ENTRY, LOG_REQUEST_DATA, LOG_DATA, LOG_REQUEST_END].

After a landing the list is asked for (LOG_REQUEST_LIST 0..0xFFFF); the newest entry
(LOG_ENTRY.last_log_num) is the flight just flown. Its bytes are asked for in windows of
at most WINDOW_BYTES (LOG_REQUEST_DATA id, ofs, count) and come back as LOG_DATA of up to
90 bytes, written to `<name>.part` in order; a window not complete within WINDOW_TIMEOUT_S
is asked for again from its first missing byte. The part file is the resume point: a
fetch cut by a lost link, an agent restart or a new arming goes on from its size.
LOG_REQUEST_END is sent when done or abandoned, so the autopilot resumes normal logging.

Rate bound: window starts are paced to `rate` bytes per second (default RATE_BYTES_S)
and one window at a time is outstanding, so the log never takes more than that however
fast the autopilot answers. On a serial link, whose capacity is known (baud / 10 bytes
per second with 8N1 framing), the rate is at most LINK_SHARE of it, and a window is at
most WINDOW_S seconds of that rate: the autopilot's answer to one window holds the link
for at most LINK_SHARE × WINDOW_S (125 ms), and commands, their acknowledgements and
telemetry go on between windows. Fetching only runs while the vehicle is disarmed:
arming stops it at once.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

LOG_DATA_BYTES = 90  # LOG_DATA.data: uint8_t[90]
WINDOW_BYTES = 90 * 32
WINDOW_TIMEOUT_S = 1.0
LIST_TIMEOUT_S = 3.0
RATE_BYTES_S = 32 * 1024
MAX_STALLS = 20  # windows in a row with nothing new: the fetch gives up for now
LINK_SHARE = 0.5
WINDOW_S = 0.25


def link_capacity(link_url: str) -> float | None:
    """Bytes per second a serial link carries (8N1: 10 bits a byte); None for TCP/UDP,
    whose capacity is not known here."""
    from onboard.links import LinkError, parse_link_url

    try:
        spec = parse_link_url(link_url)
    except LinkError:
        return None
    return spec.baud / 10.0 if spec.kind == "serial" else None


def paced(rate: float, capacity: float | None) -> tuple[float, int]:
    """The fetch's rate and window for a link of `capacity` bytes per second."""
    if capacity is None:
        return rate, WINDOW_BYTES
    rate = min(rate, capacity * LINK_SHARE)
    window = int(rate * WINDOW_S) // LOG_DATA_BYTES * LOG_DATA_BYTES
    return rate, max(LOG_DATA_BYTES, min(WINDOW_BYTES, window))


class FetchPaused(Exception):
    """The fetch stopped before the end (armed, link lost, no answer); the part file keeps
    what came, and the next try goes on from there."""


@dataclass(frozen=True)
class LogEntry:
    id: int
    size: int
    time_utc: int
    last_log_num: int


class LogFetcher:
    """Fetches the newest log of a MavlinkFlightController into `folder`."""

    def __init__(
        self,
        fc: Any,
        folder: Path,
        *,
        rate: float = RATE_BYTES_S,
        armed: Callable[[], bool] | None = None,
    ) -> None:
        self.fc = fc
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.rate, self.window = paced(rate, link_capacity(getattr(fc, "link_url", "")))
        self.armed = armed or (lambda: bool(fc.state.armed))
        self._lock = threading.Lock()
        self._entries: dict[int, LogEntry] = {}
        self._chunks: dict[int, bytes] = {}
        self._log_id: int | None = None
        self._got = threading.Event()
        self.requested_bytes = 0
        self.windows = 0

    # -- messages from the I/O thread -----------------------------------------------------

    def on_message(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "LOG_ENTRY":
            entry = LogEntry(msg.id, msg.size, msg.time_utc, msg.last_log_num)
            with self._lock:
                self._entries[entry.id] = entry
            self._got.set()
        elif kind == "LOG_DATA":
            with self._lock:
                if msg.id == self._log_id and msg.count:
                    self._chunks[msg.ofs] = bytes(msg.data[: msg.count])
            self._got.set()

    # -- the fetch ------------------------------------------------------------------------

    def _target(self) -> tuple[int, int]:
        return self.fc.target_system, self.fc.target_component

    def newest(self) -> LogEntry | None:
        """LOG_REQUEST_LIST and the entry of the last log, None when there is none."""
        with self._lock:
            self._entries.clear()
        self.fc.send("log_request_list", *self._target(), 0, 0xFFFF)
        deadline = time.monotonic() + LIST_TIMEOUT_S
        while time.monotonic() < deadline:
            self._got.wait(0.1)
            self._got.clear()
            with self._lock:
                entries = dict(self._entries)
            if entries:
                last = next(iter(entries.values())).last_log_num
                if last in entries and entries[last].size > 0:
                    return entries[last]
        return None

    def fetch_newest(self, extension: str, stem: str) -> Path | None:
        """The newest log, whole, as `<stem>_<id>.<extension>`; None when the flight
        controller has no log. Raises FetchPaused when it stops before the end."""
        self.fc.add_message_handler(self.on_message)
        try:
            entry = self.newest()
            if entry is None:
                return None
            final = self.folder / f"{stem}_{entry.id}.{extension}"
            if final.exists() and final.stat().st_size == entry.size:
                return final
            self._download(entry, final.with_name(final.name + ".part"))
            final.with_name(final.name + ".part").replace(final)
            return final
        finally:
            self._end()
            self.fc.remove_message_handler(self.on_message)

    def _end(self) -> None:
        try:
            self.fc.send("log_request_end", *self._target())
        except Exception:  # noqa: BLE001 - the link is gone: nothing to end
            pass
        with self._lock:
            self._log_id = None
            self._chunks.clear()

    def _download(self, entry: LogEntry, part: Path) -> None:
        with self._lock:
            self._log_id = entry.id
            self._chunks.clear()
        bucket_at, stalls = time.monotonic(), 0
        with open(part, "ab") as out:
            while (offset := out.tell()) < entry.size:
                if self.armed():
                    raise FetchPaused("the vehicle armed")
                count = min(self.window, entry.size - offset)
                # One window outstanding, its start paced to `rate` bytes per second.
                bucket_at = max(bucket_at, time.monotonic())
                time.sleep(max(0.0, bucket_at - time.monotonic()))
                bucket_at += count / self.rate
                self.fc.send("log_request_data", *self._target(), entry.id, offset, count)
                self.requested_bytes += count
                self.windows += 1
                written = self._collect(out, offset, offset + count)
                stalls = 0 if written else stalls + 1
                if stalls >= MAX_STALLS:
                    raise FetchPaused(f"no LOG_DATA at offset {offset}")

    def _collect(self, out: Any, start: int, end: int) -> int:
        """Write the window's LOG_DATA in order as they come; the bytes written."""
        deadline = time.monotonic() + WINDOW_TIMEOUT_S
        offset = start
        while offset < end and time.monotonic() < deadline:
            with self._lock:
                data = self._chunks.pop(offset, None)
            if data is None:
                self._got.wait(0.05)
                self._got.clear()
                continue
            out.write(data)
            offset += len(data)
            deadline = time.monotonic() + WINDOW_TIMEOUT_S
        out.flush()
        with self._lock:  # what came out of order is asked for again with the next window
            self._chunks = {o: d for o, d in self._chunks.items() if o >= offset}
        return offset - start

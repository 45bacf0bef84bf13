"""The skeleton every flight-controller driver on a byte link shares.

An I/O thread reads the link, hands bytes to the driver's decoder and keeps the session
alive (reopening the line when it vanishes, starting afresh on a new one); a second thread
hands telemetry objects to listeners, so a slow listener never stalls the link. Drivers
fill in the protocol: `_on_data`, `_on_new_line`, `_housekeeping`, `_set_disconnected`.
"""

from __future__ import annotations

import logging
import queue
import threading
import time

from onboard.links import LinkDown, LinkError, ReopeningLink

from .base import ObjectListener, StateHolder, VehicleState

log = logging.getLogger(__name__)


class LinkDriver:
    """Base of UAVTalkFlightController and MavlinkFlightController."""

    LINK_NAME = "flight controller"  # for log lines
    THREAD_PREFIX = "fc"

    def _init_link_driver(self, link: ReopeningLink, protocol: str) -> None:
        self.link = link
        self.stats: dict[str, int] = {"link_drops": 0, "listener_errors": 0}
        self._holder = StateHolder(VehicleState(protocol=protocol))
        self._listeners: list[ObjectListener] = []
        self._events: queue.Queue = queue.Queue(maxsize=10_000)
        self._connected = threading.Event()
        self._stop = threading.Event()
        self._rebuild = threading.Event()
        self._threads: list[threading.Thread] = []
        self._start_lock = threading.Lock()
        self._generation = 0

    # --- lifecycle --------------------------------------------------------------------
    def start(self) -> None:
        with self._start_lock:
            if self._threads:
                return  # exactly one session per driver
            self._stop.clear()
            for target, role in ((self._io_loop, "io"), (self._dispatch, "listeners")):
                thread = threading.Thread(
                    target=target, name=f"{self.THREAD_PREFIX}-{role}", daemon=True
                )
                thread.start()
                self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        self._on_stop()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout=3)
        self._threads = []
        self.link.close()
        self._set_disconnected()

    @property
    def state(self) -> VehicleState:
        return self._holder.get()

    def add_listener(self, listener: ObjectListener) -> None:
        self._listeners.append(listener)

    def wait_connected(self, timeout: float) -> bool:
        return self._connected.wait(timeout)

    def rebuild_link(self) -> None:
        """Drop and re-establish the link (the `rebuildtelemetry` command)."""
        self._rebuild.set()

    # --- what a protocol fills in -----------------------------------------------------
    def _on_stop(self) -> None:
        """Called first in stop(), before the threads are joined."""

    def _link_was_up(self) -> bool:
        return self._connected.is_set()

    def _on_new_line(self, now: float) -> None:
        """A freshly (re)opened line: start the protocol's decoding afresh."""
        raise NotImplementedError

    def _on_data(self, data: bytes, now: float) -> None:
        raise NotImplementedError

    def _housekeeping(self, now: float) -> None:
        raise NotImplementedError

    def _set_disconnected(self) -> None:
        raise NotImplementedError

    # --- threads ----------------------------------------------------------------------
    def _io_loop(self) -> None:
        while not self._stop.is_set():
            if self._rebuild.is_set():
                self._rebuild.clear()
                self.link.reopen()
                self._set_disconnected()
            try:
                data = self.link.read(4096, 0.05)
            except LinkDown as exc:
                if self._link_was_up():
                    log.warning("%s link lost: %s", self.LINK_NAME, exc)
                    self.stats["link_drops"] += 1
                self._set_disconnected()
                continue
            except LinkError as exc:
                log.error("%s link unusable: %s", self.LINK_NAME, exc)
                self._stop.wait(1.0)
                continue
            now = time.monotonic()
            if self.link.generation != self._generation:
                self._generation = self.link.generation
                self._on_new_line(now)
                self._set_disconnected()
            if data:
                self._on_data(data, now)
            try:
                self._housekeeping(now)
            except LinkDown as exc:
                log.warning("%s link lost while sending: %s", self.LINK_NAME, exc)
                self._set_disconnected()

    def _dispatch(self) -> None:
        while not self._stop.is_set():
            try:
                name, ts, values = self._events.get(timeout=0.2)
            except queue.Empty:
                continue
            for listener in list(self._listeners):
                try:
                    listener(name, ts, values)
                except Exception:  # a listener's bug must not stop the others
                    self.stats["listener_errors"] += 1
                    log.exception("telemetry listener failed on %s", name)

"""Ordered work lanes: a fixed set of threads, each item on the lane of its key.

The gateway hands every drone message to a lane chosen by the drone id, so one drone's
messages are handled in the order they arrived (a step's "started" before its
"completed") while other drones' go on in parallel, and the MQTT network thread never
waits on the database, Redis or a picture decoder. Heartbeats, stored many at once,
go instead to one `BatchQueue`, which one thread empties in arrival order.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable
from typing import Any

log = logging.getLogger(__name__)

_STOP = object()


class Lanes:
    """`count` threads named `<name>-<i>` calling `work(item)` in submission order per key."""

    def __init__(
        self,
        name: str,
        count: int,
        work: Callable[[Any], None],
        *,
        on_exit: Callable[[], None] = lambda: None,
    ) -> None:
        if count < 1:
            raise ValueError("a lane set needs at least one lane")
        self.work = work
        self.on_exit = on_exit
        self._queues: list[queue.SimpleQueue] = [queue.SimpleQueue() for _ in range(count)]
        self._threads = [
            threading.Thread(target=self._run, args=(q,), name=f"{name}-{i}", daemon=True)
            for i, q in enumerate(self._queues)
        ]

    def start(self) -> None:
        for thread in self._threads:
            thread.start()

    def submit(self, key: str, item: Any) -> None:
        """Queue `item` behind everything submitted earlier with the same key."""
        self._queues[zlib.crc32(key.encode()) % len(self._queues)].put(item)

    def backlog(self) -> int:
        """Items waiting, not counting the ones in hand."""
        return sum(q.qsize() for q in self._queues)

    def stop(self, timeout: float) -> bool:
        """Let every lane finish what it was given, then end; True if all ended in time."""
        for q in self._queues:
            q.put(_STOP)
        deadline = time.monotonic() + timeout
        for thread in self._threads:
            if thread.is_alive() or thread.ident is not None:
                thread.join(max(0.0, deadline - time.monotonic()))
        return not any(thread.is_alive() for thread in self._threads)

    def _run(self, items: queue.SimpleQueue) -> None:
        try:
            while (item := items.get()) is not _STOP:
                try:
                    self.work(item)
                except Exception:  # noqa: BLE001 - a lane outlives any bug in its work
                    log.exception("lane work failed")
        finally:
            self.on_exit()


class BatchQueue:
    """A bounded first-in-first-out queue that one thread empties in batches.

    Filling it is one append and a flag test, so a network thread handing over tens of
    thousands of messages a second spends next to nothing per message; `take` returns
    everything waiting (up to a limit) at once, in arrival order.
    """

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self._items: deque[Any] = deque()
        self._ready = threading.Event()

    def __len__(self) -> int:
        return len(self._items)

    def put(self, item: Any) -> bool:
        """Queue `item`; False (and nothing queued) when `limit` items are waiting."""
        if len(self._items) >= self.limit:
            return False
        self._items.append(item)
        if not self._ready.is_set():
            self._ready.set()
        return True

    def take(self, most: int, timeout: float) -> list[Any]:
        """Up to `most` items in arrival order, waiting up to `timeout` for the first."""
        if not self._items:
            # Cleared, then looked again: an item put from now on sets the flag again.
            self._ready.clear()
            if not self._items:
                self._ready.wait(timeout)
        taken: list[Any] = []
        pop = self._items.popleft
        while len(taken) < most:
            try:
                taken.append(pop())
            except IndexError:
                break
        return taken

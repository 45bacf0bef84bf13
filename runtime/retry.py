"""Waiting between attempts: the one backoff every reconnect and retry loop uses.

Here, not in the ground's workers, because onboard is installed alone on drones and the
ground imports onboard, never the other way round. Standard library only.
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


class Backoff:
    """Waits that double after each failure, from `first` up to `cap`; `reset()` after a
    success. With `jitter`, each wait is spread over 0.5x..1.5x so that many clients that
    lost the same node do not all come back at once."""

    def __init__(self, first: float, cap: float, *, jitter: bool = False) -> None:
        self.first = first
        self.cap = cap
        self.jitter = jitter
        self.delay = first  # the wait the next failure gets (before jitter)

    def failed(self) -> float:
        """The wait after this failure; the next one will be twice as long (up to cap)."""
        delay = self.delay
        self.delay = min(self.delay * 2, self.cap)
        return delay * (0.5 + random.random()) if self.jitter else delay

    def reset(self) -> None:
        self.delay = self.first


def keep_connected(
    session: Callable[[], None],
    *,
    stop: threading.Event,
    backoff: Backoff,
    errors: tuple[type[BaseException], ...],
    on_lost: Callable[[BaseException, float], None],
    cleanup: Callable[[], None] = lambda: None,
) -> None:
    """Run `session` (connect, then work until the link ends) again and again until
    `stop` is set. A session that returns resets the backoff; one that raises one of
    `errors` is reported to `on_lost(error, next wait)`. `cleanup` runs after every
    session; the wait after it ends early when `stop` is set."""
    while not stop.is_set():
        try:
            session()
            backoff.reset()
        except errors as exc:
            if stop.is_set():
                break
            on_lost(exc, backoff.delay)
        finally:
            cleanup()
        if stop.wait(backoff.failed()):
            break


def retry_call(
    action: Callable[[], T],
    *,
    errors: tuple[type[BaseException], ...],
    backoff: Backoff,
    give_up: Callable[[BaseException, float], bool],
    on_retry: Callable[[BaseException, float], None],
    sleep: Callable[[float], object] = time.sleep,
) -> T:
    """`action()`, called again after a wait while it raises one of `errors`, until
    `give_up(error, next wait)` says to stop: then the error is raised."""
    while True:
        try:
            return action()
        except errors as exc:
            delay = backoff.failed()
            if give_up(exc, delay):
                raise
            on_retry(exc, delay)
            sleep(delay)

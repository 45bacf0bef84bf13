"""A stop request that SIGTERM and SIGINT can make safely, for a process's main loop."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterable
from types import FrameType

SIGNALS = (signal.SIGTERM, signal.SIGINT)


class StopSignal:
    """Set by SIGTERM or SIGINT once installed (or by `set()`), waited on by a main loop.

    Setting it takes no lock. A `threading.Event` set from a signal handler deadlocks when
    the signal arrives while the main thread is inside that event's own `wait` (the
    handler runs in the main thread and waits for a lock the main thread holds): the
    process then never stops. Here a flag is set, and `wait` sleeps in short steps.
    """

    POLL_S = 0.05

    def __init__(self) -> None:
        self.signum: int | None = None
        self._set = False

    def install(self, signals: Iterable[int] = SIGNALS) -> StopSignal:
        for signum in signals:
            signal.signal(signum, self._handle)
        return self

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.signum = signum
        self._set = True

    def set(self) -> None:
        self._set = True

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float) -> bool:
        """True once set; False when `timeout` seconds passed first."""
        deadline = time.monotonic() + timeout
        while not self._set:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(left, self.POLL_S))
        return True

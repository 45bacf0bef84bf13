"""The threads a request's synchronous work runs in, kept for the next request.

Django's ASGI handler gives each request a thread of its own for its synchronous parts
(database queries, sync views): a new thread, started on the event loop and joined at the
end. Starting and joining a thread costs the event loop as much as the rest of a small
API request. Here a request borrows an idle thread, still one request per thread at a
time, and gives it back when it is done; a thread that still has work queued (its request
was cancelled while a call ran) is retired instead, so no request ever waits behind
another's work.
"""

from __future__ import annotations

import threading
from collections.abc import AsyncIterator, Callable
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import asynccontextmanager
from typing import Any

from asgiref.sync import ThreadSensitiveContext

# Idle threads kept for later requests; more concurrent requests than this start threads
# as Django would, and retire them when they finish.
KEEP_IDLE = 32


class RequestThread(ThreadPoolExecutor):
    """One thread, one call at a time, that knows whether calls are still queued or running."""

    def __init__(self) -> None:
        super().__init__(max_workers=1, thread_name_prefix="request")
        self._lock = threading.Lock()
        self.pending = 0
        self.before_first_call: Callable[[], None] | None = None

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        first, self.before_first_call = self.before_first_call, None
        if first is not None:
            fn = _preceded(first, fn)
        future = super().submit(fn, *args, **kwargs)
        with self._lock:
            self.pending += 1
        future.add_done_callback(self._finished)
        return future

    def _finished(self, _future: Future) -> None:
        with self._lock:
            self.pending -= 1

    @property
    def idle(self) -> bool:
        with self._lock:
            return self.pending == 0


class RequestThreads:
    """A pool of `RequestThread`s; `context()` is what each request runs in."""

    def __init__(self, keep_idle: int = KEEP_IDLE) -> None:
        self.keep_idle = keep_idle
        self._idle: list[RequestThread] = []
        self._lock = threading.Lock()

    @asynccontextmanager
    async def context(
        self, before_first_call: Callable[[], None] | None = None
    ) -> AsyncIterator[RequestThread]:
        """Thread-sensitive sync calls inside run on one borrowed thread; the first of them
        runs `before_first_call` first, in that thread."""
        thread = self._borrow()
        thread.before_first_call = before_first_call
        try:
            async with ThreadSensitiveContext(executor=thread):
                yield thread
        finally:
            self._give_back(thread)

    def _borrow(self) -> RequestThread:
        with self._lock:
            if self._idle:
                return self._idle.pop()
        return RequestThread()

    def _give_back(self, thread: RequestThread) -> None:
        thread.before_first_call = None
        with self._lock:
            if thread.idle and len(self._idle) < self.keep_idle:
                self._idle.append(thread)
                return
        thread.shutdown(wait=False)

    @property
    def idle_count(self) -> int:
        with self._lock:
            return len(self._idle)


def _preceded(first: Callable[[], None], fn: Callable[..., Any]) -> Callable[..., Any]:
    def both(*args: Any, **kwargs: Any) -> Any:
        first()
        return fn(*args, **kwargs)

    return both

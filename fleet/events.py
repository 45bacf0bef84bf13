"""Push a change to every portal page of an organisation (the Channels group)."""

from __future__ import annotations

import asyncio
import logging
import threading
from concurrent.futures import Future

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer

log = logging.getLogger(__name__)


def _group(organisation_id: int) -> str:
    return f"org-{organisation_id}"


def publish_to_organisation(organisation_id: int, payload: dict) -> None:
    layer = get_channel_layer()
    if layer is None:
        return
    async_to_sync(layer.group_send)(
        _group(organisation_id), {"type": "fleet.event", "payload": payload}
    )


class _BackgroundPublisher:
    """One event loop thread that sends group messages without blocking the caller.

    The gateway handles a heartbeat on paho's network thread; waiting there for a Redis
    round trip per update would halve its rate. Losing an update on overload is fine: the
    next heartbeat carries the whole state again.
    """

    def __init__(self) -> None:
        self._loop: asyncio.AbstractEventLoop | None = None
        self._lock = threading.Lock()

    def _ensure_loop(self) -> asyncio.AbstractEventLoop:
        with self._lock:
            if self._loop is None:
                loop = asyncio.new_event_loop()
                threading.Thread(target=loop.run_forever, name="fleet-events", daemon=True).start()
                self._loop = loop
            return self._loop

    def publish(self, organisation_id: int, payload: dict) -> Future | None:
        layer = get_channel_layer()
        if layer is None:
            return None
        future = asyncio.run_coroutine_threadsafe(
            layer.group_send(_group(organisation_id), {"type": "fleet.event", "payload": payload}),
            self._ensure_loop(),
        )
        future.add_done_callback(_log_failure)
        return future


def _log_failure(future) -> None:  # type: ignore[no-untyped-def]
    if not future.cancelled() and future.exception() is not None:
        log.warning("live update not sent: %s", future.exception())


_publisher = _BackgroundPublisher()


def publish_nowait(organisation_id: int, payload: dict) -> Future | None:
    """Like publish_to_organisation, but returns at once (for the gateway's hot path).

    Works from any thread, including one where an event loop runs; wait on the returned
    future when the caller must know the message left.
    """
    return _publisher.publish(organisation_id, payload)

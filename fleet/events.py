"""Push a change to every portal page of an organisation (the Channels group)."""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from concurrent.futures import Future

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer

from .state import Motion, state_of

log = logging.getLogger(__name__)


def _group(organisation_id: int) -> str:
    return f"org-{organisation_id}"


_motion = Motion()


def with_derived_fields(payload: dict) -> dict:
    """A `drone` update with what pages derive from it: the drone's state and, for a
    heartbeat's full state, ground speed, heading and battery time left (from this
    process's previous updates of the drone)."""
    drone = payload.get("drone") if payload.get("type") == "drone" else None
    if not isinstance(drone, dict) or "drone_id" not in drone:
        return payload
    derived: dict = {}
    if "position" in drone:
        remaining = (drone.get("battery") or {}).get("remaining")
        derived = _motion.update(drone["drone_id"], time.time(), drone["position"], remaining)
    return {**payload, "drone": {**drone, **derived, "state": state_of(drone)}}


def publish_to_organisation(organisation_id: int, payload: dict) -> None:
    layer = get_channel_layer()
    if layer is None:
        return
    async_to_sync(layer.group_send)(
        _group(organisation_id), {"type": "fleet.event", "payload": with_derived_fields(payload)}
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
            layer.group_send(
                _group(organisation_id),
                {"type": "fleet.event", "payload": with_derived_fields(payload)},
            ),
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


def command_entry(entry) -> dict:  # type: ignore[no-untyped-def]
    """A command-log row as the drone page lists it."""
    return {
        "id": entry.pk,
        "command": entry.command,
        "outcome": entry.outcome,
        "outcome_label": entry.get_outcome_display(),
        "user": str(entry.user) if entry.user_id else None,
        "error": entry.error,
        "sent_at": entry.sent_at.isoformat() if entry.sent_at else None,
    }


def command_logged(sender, instance, **kwargs) -> None:  # type: ignore[no-untyped-def]
    """post_save of a CommandLog: the drone's page shows the command, then its outcome."""
    drone = instance.drone
    publish_nowait(
        drone.organisation_id,
        {"type": "command", "drone_id": drone.drone_id, "command": command_entry(instance)},
    )

"""The past-view process: broker in, Channels groups and Redis snapshots out.

Why a process of its own rather than a handler in the gateway: the selection runs for
every pose (up to 200 Hz per drone, each evaluating the whole buffer) and needs the
telemetry stream, which the gateway does not read. In the gateway it would compete with
the command path on the same MQTT thread; here it cannot delay a command reply.

One process serves every drone. It subscribes to ``+/camera/out`` and
``+/telemetry/out`` without a shared subscription: a drone's frames and poses must reach
the same ``PastView``, and a ``$share`` group would split them between processes.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import socket
import threading
import time
from collections import Counter
from datetime import UTC, datetime
from typing import Any

import redis
from channels.layers import get_channel_layer
from django.conf import settings
from django.db import close_old_connections

from pastview.models import ViewSettings
from pastview.selection import PastViewSettings
from pastview.service import PastViewService, group_name
from runtime.stopsignal import StopSignal
from workers import broker, outbox
from workers.broker.client import Listener
from workers.counters import Heartbeat, start_heartbeat

log = logging.getLogger("pastview")

SNAPSHOT_PREFIX = "skyhive:pastview:snapshot:"
SNAPSHOT_TTL_S = 3600
# Pages mark their drone as watched (drone id -> expiry, epoch seconds) and renew the mark
# every third of this; the service pushes only for marked drones.
WATCH_KEY = "skyhive:pastview:watched"
WATCH_TTL_S = 60.0
TOPICS = ("+/camera/out", "+/telemetry/out")


def snapshot_key(drone_id: str) -> str:
    return SNAPSHOT_PREFIX + drone_id


def load_snapshot(drone_id: str) -> dict[str, Any] | None:
    """The latest state the service stored for a drone (for a page that just connected)."""
    raw = outbox.sync_redis().get(snapshot_key(drone_id))
    return None if raw is None else json.loads(raw)


async def amark_watched(client: Any, drone_id: str) -> None:
    """Called by a page's consumer on connect and then every WATCH_TTL_S / 3."""
    await client.hset(WATCH_KEY, drone_id, time.time() + WATCH_TTL_S)


def watched_drones(client: Any) -> set[str]:
    """Drones with a live mark; expired marks are removed on the way."""
    now = time.time()
    marks = {
        k.decode() if isinstance(k, bytes) else k: float(v)
        for k, v in client.hgetall(WATCH_KEY).items()
    }
    expired = [d for d, until in marks.items() if until <= now]
    if expired:
        client.hdel(WATCH_KEY, *expired)
    return {d for d, until in marks.items() if until > now}


def _settings_for(drone_id: str) -> PastViewSettings | None:
    try:
        return ViewSettings.objects.for_drone_id(drone_id)
    finally:
        close_old_connections()


class GroupPublisher:
    """Sends to Channels groups from any thread through one event-loop thread, so the MQTT
    thread never waits for Redis.

    One sender drains a queue in order: concurrent sends could overtake each other, and a
    page must not get a frame's relative pose before the frame's image.
    """

    def __init__(self, max_queued: int = 10_000) -> None:
        self.layer = get_channel_layer()
        self.loop = asyncio.new_event_loop()
        self.failed = 0
        self.overflowed = 0
        self.queue: asyncio.Queue = asyncio.Queue(max_queued)
        self.thread = threading.Thread(target=self._run, name="pastview-push", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        drain = self.loop.create_task(self._drain())
        self.loop.run_forever()
        drain.cancel()
        self.loop.run_until_complete(asyncio.gather(drain, return_exceptions=True))
        self.loop.close()

    def __call__(self, drone_id: str, message: dict[str, Any]) -> None:
        self.loop.call_soon_threadsafe(self._put, drone_id, message)

    def _put(self, drone_id: str, message: dict[str, Any]) -> None:
        try:
            self.queue.put_nowait((drone_id, message))
        except asyncio.QueueFull:
            self.overflowed += 1  # Redis is away or slow: the latest state comes again soon

    async def _drain(self) -> None:
        while True:
            drone_id, message = await self.queue.get()
            try:
                await self.layer.group_send(
                    group_name(drone_id), {"type": "pastview.message", "message": message}
                )
            except Exception as exc:  # noqa: BLE001 - keep sending the next ones
                self.failed += 1
                if self.failed % 100 == 1:
                    log.warning("group send failed (%d so far): %s", self.failed, exc)

    def close(self) -> None:
        """Stop after what is queued now has been sent (or two seconds)."""
        self.loop.call_soon_threadsafe(self._stop_when_drained)
        self.thread.join(2.0)

    def _stop_when_drained(self) -> None:
        if self.queue.empty():
            self.loop.stop()
        else:
            self.loop.call_later(0.01, self._stop_when_drained)


class PastViewProcess:
    """The service on the broker package's listener; ``tick`` is called by the main loop.

    `broker_url` is one node or several (as `broker.cluster_urls` reads it): the listener
    moves to the next node when one goes, as the other ground processes do.
    """

    def __init__(self, broker_url: str, *, client_id: str | None = None) -> None:
        self.redis = redis.Redis.from_url(settings.REDIS_URL, socket_timeout=2)
        self.publisher = GroupPublisher()
        self.service = PastViewService(
            publish=self.publisher,
            remember=self._remember,
            settings_for=_settings_for,
            push_hz=settings.PASTVIEW_PUSH_HZ,
        )
        self.listener = Listener(
            broker.cluster_urls(broker_url),
            client_id or f"pastview-{socket.gethostname()}-{os.getpid()}",
            TOPICS,
            self._on_message,
            name="pastview",
        )
        self.connected = self.listener.connected
        self.subscribed = self.listener.subscribed
        self._settings_seen = time.time()
        self._applied: dict[str, Any] = {}  # drone id -> updated_at of the settings applied
        self._next_status = 0.0
        self._next_watch = 0.0
        self._next_report = 0.0
        self._reported: Counter[str] = Counter()
        self.heartbeat: Heartbeat

    @property
    def address(self) -> str:
        """The broker node the listener is on (or trying), as `host:port`."""
        node = self.listener.failover.current
        return f"{node.host}:{node.port}"

    def start(self) -> None:
        self.refresh_watched()
        self.listener.start()

    def stop(self) -> None:
        self.listener.stop()
        self.publisher.close()
        close_old_connections()

    def _on_message(self, topic: str, payload: bytes) -> None:
        try:
            self.service.handle(topic, payload)
        except Exception:  # noqa: BLE001 - no message may stop the view
            self.service.counters["dropped.handler_error"] += 1
            log.exception("handling %s failed", topic)

    def _remember(self, drone_id: str, snapshot: dict[str, Any]) -> None:
        self.redis.set(snapshot_key(drone_id), json.dumps(snapshot), ex=SNAPSHOT_TTL_S)

    def tick(self) -> None:
        """Push held-back updates; four times a second, read which drones pages are open on
        (a new page waits at most that long for pushes); every two seconds, apply edited
        settings and send status."""
        self.service.flush()
        now = time.monotonic()
        if now >= self._next_watch:
            self._next_watch = now + 0.25
            self.refresh_watched()
        if now < self._next_status:
            return
        self._next_status = now + 2.0
        self.reload_settings()
        self.service.publish_status()

    def refresh_watched(self) -> None:
        try:
            self.service.watched = watched_drones(self.redis)
        except redis.RedisError as exc:
            if self.service.watched is not None:  # say it once per outage, not 4 times a second
                log.warning("watched drones unknown (%s): pushing for all", exc)
            self.service.watched = None

    def reload_settings(self) -> int:
        """Apply settings edited since the last look; how many drones changed."""
        since = datetime.fromtimestamp(self._settings_seen - 5.0, tz=UTC)
        self._settings_seen = time.time()
        changed = 0
        try:
            rows = list(ViewSettings.objects.filter(updated_at__gte=since).select_related("drone"))
        except Exception:  # noqa: BLE001 - keep serving with the settings in hand
            log.exception("settings not reloaded")
            return 0
        finally:
            close_old_connections()
        for row in rows:
            if self._applied.get(row.drone.drone_id) == row.updated_at:
                continue  # the look-back window sees a row more than once
            self._applied[row.drone.drone_id] = row.updated_at
            try:
                self.service.apply_settings(row.drone.drone_id, row.past_view_settings())
                changed += 1
            except ValueError as exc:
                log.warning("settings of %s refused: %s", row.drone.drone_id, exc)
        return changed

    def report(self) -> None:
        """Hand the service's totals to the instance report (operations page, /health)."""
        for name, value in list(self.service.counters.items()):
            delta = value - self._reported[name]
            if delta:
                self.heartbeat.counters.incr(name, delta)
                self._reported[name] = value

    def run(self, stopping: threading.Event | StopSignal) -> None:
        self.heartbeat = start_heartbeat("pastview")
        self.start()
        period = min(0.02, 0.5 / settings.PASTVIEW_PUSH_HZ)
        try:
            while not stopping.wait(period):
                self.tick()
                if time.monotonic() >= self._next_report:
                    self._next_report = time.monotonic() + 1.0
                    self.report()
        finally:
            self.stop()
            self.report()
            self.heartbeat.counters.flush()
            self.heartbeat.stop()

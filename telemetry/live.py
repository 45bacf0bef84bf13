"""Live telemetry for dashboards: which drones are watched, and pushing their latest values.

The ingest process pushes at most `TELEMETRY_LIVE_HZ` times a second per drone, and only
for drones a dashboard is open on, so a thousand unwatched drones cost nothing.
"""

from __future__ import annotations

import time

import redis
from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer
from django.conf import settings

WATCH_KEY = "skyhive:telemetry:watched"
WATCH_TTL_S = 60.0


def group_name(drone_pk: int) -> str:
    """The Channels group a drone's dashboards listen on."""
    return f"telemetry-{drone_pk}"


def _redis() -> redis.Redis:
    return redis.Redis.from_url(settings.REDIS_URL, socket_timeout=1, decode_responses=True)


def mark_watched(drone_pk: int) -> None:
    """Called by the websocket consumer on connect and then every WATCH_TTL_S / 3."""
    _redis().hset(WATCH_KEY, str(drone_pk), time.time() + WATCH_TTL_S)


def watched_drones() -> set[int]:
    """Drones a dashboard marked in the last WATCH_TTL_S; forgets the expired marks."""
    client = _redis()
    now = time.time()
    marks = client.hgetall(WATCH_KEY)
    expired = [pk for pk, until in marks.items() if float(until) <= now]
    if expired:
        client.hdel(WATCH_KEY, *expired)
    return {int(pk) for pk, until in marks.items() if float(until) > now}


class ChannelsLivePublisher:
    """The ingestor's `live` callback: latest values of watched drones to their groups."""

    def __init__(self, refresh_every: float = 1.0) -> None:
        self.layer = get_channel_layer()
        self.refresh_every = refresh_every
        self._watched: set[int] = set()
        self._checked = 0.0

    def __call__(self, latest: dict[int, dict[str, tuple[float, dict]]]) -> None:
        if time.monotonic() - self._checked >= self.refresh_every:
            try:
                self._watched = watched_drones()
            except redis.RedisError:
                pass
            self._checked = time.monotonic()
        for drone_pk, objects in latest.items():
            if drone_pk not in self._watched:
                continue
            async_to_sync(self.layer.group_send)(
                group_name(drone_pk),
                {
                    "type": "telemetry.update",
                    "objects": {
                        name: {"ts": ts, "fields": fields} for name, (ts, fields) in objects.items()
                    },
                },
            )

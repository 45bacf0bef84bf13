"""Process counters (received, dropped, …) shared through Redis for /health and the admin.

Long-running processes count in memory and flush every second, so the hot path never
waits on Redis.
"""

from __future__ import annotations

import threading
import time
from collections import Counter

import redis
from django.conf import settings

KEY_PREFIX = "skyhive:counters:"


def _client() -> redis.Redis:
    return redis.Redis.from_url(settings.REDIS_URL, socket_timeout=1, decode_responses=True)


class Counters:
    """In-memory counters for one process, flushed to a Redis hash named after it."""

    def __init__(self, process: str, flush_every: float = 1.0):
        self.process = process
        self.flush_every = flush_every
        self._counts: Counter[str] = Counter()
        self._gauges: dict[str, float] = {}
        self._lock = threading.Lock()
        self._last_flush = 0.0

    def incr(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self._counts[name] += amount

    def gauge(self, name: str, value: float) -> None:
        with self._lock:
            self._gauges[name] = value

    def get(self, name: str) -> int:
        with self._lock:
            return self._counts[name]

    def maybe_flush(self) -> None:
        if time.monotonic() - self._last_flush >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        with self._lock:
            counts = dict(self._counts)
            self._counts.clear()
            gauges = dict(self._gauges)
        self._last_flush = time.monotonic()
        if not counts and not gauges:
            return
        try:
            client = _client()
            pipe = client.pipeline()
            key = KEY_PREFIX + self.process
            for name, amount in counts.items():
                pipe.hincrby(key, name, amount)
            for name, value in gauges.items():
                pipe.hset(key, name, value)
            pipe.hset(key, "updated_at", time.time())
            pipe.execute()
        except redis.RedisError:
            # Keep the counts for the next flush rather than losing them.
            with self._lock:
                self._counts.update(counts)


def snapshot() -> dict[str, dict[str, float]]:
    """Every process's counters, for /health and the status page."""
    client = _client()
    out: dict[str, dict[str, float]] = {}
    for key in client.scan_iter(KEY_PREFIX + "*"):
        values = client.hgetall(key)
        out[key[len(KEY_PREFIX) :]] = {name: float(value) for name, value in values.items()}
    return out

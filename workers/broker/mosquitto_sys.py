"""Mosquitto's `$SYS/broker/...` figures, as the gateways keep seeing them.

Mosquitto publishes its client and subscription counts only when they change, retained
with a 60 s message expiry: a look at `$SYS` a minute after the last change finds no
`clients/connected` at all. So every gateway on Mosquitto also subscribes to
`$SYS/broker/#` and keeps what it sees in a Redis hash of its own
(`skyhive:mosquitto-sys:<instance>`), emptied when it (re)connects, renewed while it runs
and gone soon after it stops. A gateway that has a figure has seen its latest value: it was
subscribed when the value last changed, or it got the retained message on connecting.
"""

from __future__ import annotations

import threading
import time

import redis

# The $SYS topics (under $SYS/broker/) and the names the operations page shows them by.
MOSQUITTO_SYS = {
    "clients/connected": "clients_connected",
    "clients/total": "clients_total",
    "messages/stored": "messages_stored",
    "store/messages/count": "store_messages",
    "publish/messages/dropped": "messages_dropped",
    "publish/messages/received": "messages_received",
    "publish/messages/sent": "messages_sent",
    "subscriptions/count": "subscriptions",
    "shared_subscriptions/count": "shared_subscriptions",
    "load/messages/received/1min": "received_per_min",
    "uptime": "uptime",
    "version": "version",
}
SYS_FILTER = "$SYS/broker/#"
KEY_PREFIX = "skyhive:mosquitto-sys:"
VIEW_TTL_S = 30.0  # a stopped gateway's view is dropped this soon
RENEW_EVERY_S = 5.0


def figure_name(topic: str) -> str | None:
    """Our name for a $SYS topic, None for one we do not show (or not a $SYS topic)."""
    if not topic.startswith("$SYS/broker/"):
        return None
    return MOSQUITTO_SYS.get(topic.removeprefix("$SYS/broker/"))


def parse(text: str) -> int | float | str:
    """`12` → 12, `0.5` → 0.5, anything else (`mosquitto version 2.0.11`) as it is."""
    try:
        return float(text) if "." in text else int(text)
    except ValueError:
        return text


class SysView:
    """One gateway's view. `remember` and `reset` only touch memory (they run on the MQTT
    network thread); `flush`, called from the gateway's outbox loop, writes to Redis and
    swallows its errors: the figures are a nicety, the gateway's work comes first."""

    def __init__(self, client: redis.Redis, instance: str) -> None:
        self.client = client
        self.key = KEY_PREFIX + instance
        self._lock = threading.Lock()
        self._seen: dict[str, str] = {}
        self._dirty = False
        self._clear = False
        self._renewed = 0.0

    def reset(self) -> None:
        """A new connection (or a stop): what was seen may have changed unseen meanwhile."""
        with self._lock:
            self._seen.clear()
            self._dirty, self._clear = False, True

    def remember(self, topic: str, payload: bytes) -> bool:
        name = figure_name(topic)
        if name is None:
            return False
        with self._lock:
            self._seen[name] = payload.decode(errors="replace")
            self._dirty = True
        return True

    def flush(self, now: float | None = None) -> None:
        """Write what changed, or renew the view's expiry every few seconds."""
        now = time.monotonic() if now is None else now
        with self._lock:
            clear, dirty = self._clear, self._dirty
            seen = dict(self._seen) if dirty else {}
            self._clear = self._dirty = False
        if not (clear or dirty) and now - self._renewed < RENEW_EVERY_S:
            return
        self._renewed = now
        try:
            pipe = self.client.pipeline(transaction=False)
            if clear:
                pipe.delete(self.key)
            if seen:
                pipe.hset(self.key, mapping={**seen, "at": time.time()})
            if seen or not clear:
                pipe.expire(self.key, int(VIEW_TTL_S))
            pipe.execute()
        except redis.RedisError:
            with self._lock:  # try again on the next flush
                self._clear |= clear
                self._dirty |= dirty


def remembered(client: redis.Redis) -> dict[str, int | float | str]:
    """The figures the running gateways hold, the most recently updated view first."""
    views = []
    for key in client.scan_iter(KEY_PREFIX + "*", count=100):
        values = {_text(k): _text(v) for k, v in client.hgetall(key).items()}
        if values:
            views.append(values)
    views.sort(key=lambda v: float(v.get("at", 0)))
    merged: dict[str, int | float | str] = {}
    for view in views:  # later (more recent) views win
        for name, text in view.items():
            if name != "at":
                merged[name] = parse(text)
    return merged


def fill_in(read: dict[str, str], held: dict[str, int | float | str]) -> tuple[dict, list[str]]:
    """The figures of one $SYS read, completed with the gateways' `held` ones where the
    read has none (expired); also which names came from the gateways."""
    figures: dict[str, int | float | str] = {name: parse(text) for name, text in read.items()}
    from_gateways = sorted(set(held) - set(figures))
    figures.update({name: held[name] for name in from_gateways})
    return figures, from_gateways


def _text(value: bytes | str) -> str:
    """Redis answers bytes or str, as its client was made."""
    return value.decode(errors="replace") if isinstance(value, bytes) else value

"""Mosquitto's `$SYS/broker/...` figures, as the gateways keep seeing them.

Mosquitto publishes its client and subscription counts only when they change, retained
with a 60 s message expiry: a look at `$SYS` a minute after the last change finds no
`clients/connected` at all. So every gateway on Mosquitto also subscribes to
`$SYS/broker/#` and keeps what it sees in a Redis hash of its own
(`skyhive:mosquitto-sys:<instance>`), emptied when it (re)connects, renewed while it runs
and gone soon after it stops. A gateway that has a figure has seen its latest value: it was
subscribed when the value last changed, or it got the retained message on connecting.
The hash also says which node the gateway is linked to and whether the link is up (else
why not), so the operations page can tell a node that is down without connecting itself.
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
# The hash's own fields, besides the figures and `at` (when it was written).
ADDRESS, LINK, ERROR = "_address", "_link", "_error"
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
    """One gateway's view. `remember`, `reset`, `link_up` and `link_down` only touch
    memory (they run on the MQTT network thread); `flush`, called from the gateway's outbox
    loop, writes to Redis and swallows its errors: the figures are a nicety, the gateway's
    work comes first."""

    def __init__(self, client: redis.Redis, instance: str) -> None:
        self.client = client
        self.key = KEY_PREFIX + instance
        self._lock = threading.Lock()
        self._seen: dict[str, str] = {}
        self._link: dict[str, str] = {}
        self._dirty = False
        self._clear = False
        self._renewed = 0.0

    def reset(self) -> None:
        """A new connection (or a stop): what was seen may have changed unseen meanwhile."""
        with self._lock:
            self._seen.clear()
            self._link = {}
            self._dirty, self._clear = False, True

    def link_up(self, address: str) -> None:
        """Connected to the node at `address` (`host:port`); forgets what was seen."""
        self.reset()
        with self._lock:
            self._link = {ADDRESS: address, LINK: "up", ERROR: ""}
            self._dirty = True

    def link_down(self, address: str, error: str) -> None:
        """Not connected to `address`, because of `error`."""
        self.reset()
        with self._lock:
            self._link = {ADDRESS: address, LINK: "down", ERROR: error}
            self._dirty = True

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
            seen = {**self._seen, **self._link} if dirty else {}
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


def views(client: redis.Redis) -> list[dict[str, str]]:
    """Every running gateway's view as it stored it, the least recently written first."""
    found = []
    for key in client.scan_iter(KEY_PREFIX + "*", count=100):
        values = {_text(k): _text(v) for k, v in client.hgetall(key).items()}
        if values:
            found.append(values)
    found.sort(key=lambda v: float(v.get("at", 0)))
    return found


def merged(held: list[dict[str, str]]) -> dict[str, int | float | str]:
    """The figures of several views (least recent first), the more recent ones winning."""
    figures: dict[str, int | float | str] = {}
    for view in held:
        for name, text in view.items():
            if name != "at" and not name.startswith("_"):
                figures[name] = parse(text)
    return figures


def remembered(client: redis.Redis) -> dict[str, int | float | str]:
    """The figures the running gateways hold, the most recently seen winning."""
    return merged(views(client))


def _text(value: bytes | str) -> str:
    """Redis answers bytes or str, as its client was made."""
    return value.decode(errors="replace") if isinstance(value, bytes) else value

"""/health: is every part up? 200 when the database, Redis and the broker answer, else 503.

With a clustered broker each node is checked; the broker counts as up (status "degraded",
still 200) while at least one node answers, since drones and ground processes fail over.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as mqtt
import redis
from django.conf import settings
from django.db import connection
from django.http import HttpRequest, JsonResponse


def check_database() -> str | None:
    try:
        with connection.cursor() as cursor:
            cursor.execute("SELECT 1")
        return None
    except Exception as exc:  # noqa: BLE001 - any failure means "down", with its reason
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def check_redis() -> str | None:
    try:
        redis.Redis.from_url(settings.REDIS_URL, socket_timeout=1).ping()
        return None
    except redis.RedisError as exc:
        return str(exc)


def broker_node_urls() -> list[str]:
    """The ground's URL of every broker node: MQTT_URLS for a RabbitMQ cluster, else the
    one Mosquitto of MQTT_URL."""
    if settings.MQTT_BROKER == "rabbitmq" and settings.MQTT_URLS:
        return list(settings.MQTT_URLS)
    return [settings.MQTT_URL]


def check_broker_node(url: str, timeout: float = 2.0) -> str | None:
    """A real MQTT CONNECT with the ground's credentials to one node."""
    parts = urlsplit(url)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="", clean_session=True)
    if parts.username:
        client.username_pw_set(unquote(parts.username), unquote(parts.password or ""))
    result: dict[str, object] = {}
    client.on_connect = lambda c, u, f, rc, p: result.setdefault("rc", rc)
    try:
        client.connect(parts.hostname or "127.0.0.1", parts.port or 1883, keepalive=5)
    except OSError as exc:
        return str(exc) or type(exc).__name__
    deadline = time.monotonic() + timeout
    while "rc" not in result and time.monotonic() < deadline:
        client.loop(timeout=0.1)
    client.disconnect()
    rc = result.get("rc")
    if rc is None:
        return "no CONNACK from the broker"
    if getattr(rc, "is_failure", False):
        return f"broker refused the connection: {rc}"
    return None


def check_broker_nodes(timeout: float = 2.0) -> dict[str, str | None]:
    """Each node's error (None when up), keyed `host:port`, checked in parallel so a dead
    node costs one timeout, not one per node."""
    urls = broker_node_urls()
    with ThreadPoolExecutor(max_workers=len(urls)) as pool:
        errors = list(pool.map(lambda url: check_broker_node(url, timeout), urls))
    return {_address(url): error for url, error in zip(urls, errors, strict=True)}


def check_broker(timeout: float = 2.0) -> str | None:
    """None while at least one node answers; else every node's reason."""
    nodes = check_broker_nodes(timeout)
    if any(error is None for error in nodes.values()):
        return None
    if len(nodes) == 1:
        return next(iter(nodes.values()))
    return "; ".join(f"{address}: {error}" for address, error in nodes.items())


def _address(url: str) -> str:
    parts = urlsplit(url)
    return f"{parts.hostname or '127.0.0.1'}:{parts.port or 1883}"


def _broker_summary(nodes: dict[str, str | None]) -> tuple[str | None, str]:
    """(error, what /health shows): "ok"; "degraded: ..." when some nodes of a cluster are
    down but one answers (still up: drones fail over); the reasons when none answers."""
    down = {address: error for address, error in nodes.items() if error is not None}
    if not down:
        return None, "ok"
    if len(down) < len(nodes):
        listed = "; ".join(f"{address} down ({error})" for address, error in down.items())
        return None, f"degraded: {listed}"
    if len(nodes) == 1:
        error = next(iter(down.values()))
        return error, error or "down"
    listed = "; ".join(f"{address}: {error}" for address, error in down.items())
    return listed, listed


def health(request: HttpRequest) -> JsonResponse:
    nodes = check_broker_nodes()
    broker_error, broker_shown = _broker_summary(nodes)
    checks = {"database": check_database(), "redis": check_redis(), "broker": broker_error}
    shown = {name: ("ok" if error is None else error) for name, error in checks.items()}
    shown["broker"] = broker_shown
    degraded = broker_error is None and broker_shown != "ok"
    failed = any(error is not None for error in checks.values())
    body: dict[str, object] = {
        "status": "error" if failed else ("degraded" if degraded else "ok"),
        "checks": shown,
    }
    if len(nodes) > 1:
        body["broker_nodes"] = {
            address: "ok" if error is None else error for address, error in nodes.items()
        }
    if checks["redis"] is None:
        from workers.counters import snapshot

        body["processes"] = snapshot()
    return JsonResponse(body, status=503 if failed else 200)

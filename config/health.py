"""/health: is every part up? 200 when the database, Redis and the broker answer, else 503.

Anyone may ask, so an anonymous caller gets only the status word; staff users also get
each part's state, its error text, the broker nodes and the process counters. The checks
run at most once per HEALTH_CACHE_S in each web process, however often /health is asked.

On Mosquitto the broker is up when a running gateway reports its link to it as up (the
view the gateways keep in Redis, workers/broker/mosquitto_sys.py): no request opens an MQTT
connection of its own. A RabbitMQ cluster's MQTT listeners are each connected to, once per
cache period, since the gateways' figures there come from the management API; the broker
counts as up (status "degraded", still 200) while at least one node answers, as drones and
ground processes fail over.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any
from urllib.parse import urlsplit

import redis
from django.conf import settings
from django.db import connection
from django.http import HttpRequest, JsonResponse

from onboard.mqtt import parse_broker_url
from workers.broker import mosquitto_sys, probe
from workers.broker.figures import mosquitto_figures

_lock = threading.Lock()
_cached: tuple[float, dict[str, Any]] | None = None


def check_database() -> str | None:
    try:
        with connection.cursor() as cursor:
            cursor.execute("SELECT 1")
        return None
    except Exception as exc:  # noqa: BLE001 - any failure means "down", with its reason
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _redis() -> redis.Redis:
    return redis.Redis.from_url(settings.REDIS_URL, socket_timeout=1)


def check_redis() -> str | None:
    try:
        _redis().ping()
        return None
    except redis.RedisError as exc:
        return str(exc)


def broker_node_urls() -> list[str]:
    """The ground's URL of every broker node: MQTT_URLS for a RabbitMQ cluster, else the
    one Mosquitto of MQTT_URL."""
    if settings.MQTT_BROKER == "rabbitmq" and settings.MQTT_URLS:
        return list(settings.MQTT_URLS)
    return [settings.MQTT_URL]


def check_mosquitto() -> dict[str, str | None]:
    """The Mosquitto node's error (None when up) as the running gateways report it."""
    node = parse_broker_url(settings.MQTT_URL)  # as the gateways name the node they are on
    address = f"{node.host}:{node.port}"
    try:
        figures = mosquitto_figures(mosquitto_sys.views(_redis()), address)
    except redis.RedisError as exc:
        return {address: f"unknown: the gateways' reports are in Redis, which fails ({exc})"}
    up = figures.get("nodes_up", 0) > 0
    return {address: None if up else figures.get("error") or "down"}


def check_broker_nodes(timeout: float = 2.0) -> dict[str, str | None]:
    """Each node's error (None when up), keyed `host:port`. RabbitMQ nodes are connected
    to in parallel, so a dead node costs one timeout, not one per node."""
    if settings.MQTT_BROKER != "rabbitmq":
        return check_mosquitto()
    urls = broker_node_urls()
    with ThreadPoolExecutor(max_workers=len(urls)) as pool:
        errors = list(pool.map(lambda url: probe.connect_error(url, timeout), urls))
    return {_address(url): error for url, error in zip(urls, errors, strict=True)}


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


def run_checks() -> dict[str, Any]:
    """Every part's state: the status word, each part's text, and the broker's nodes."""
    nodes = check_broker_nodes()
    broker_error, broker_shown = _broker_summary(nodes)
    checks = {"database": check_database(), "redis": check_redis(), "broker": broker_error}
    shown = {name: ("ok" if error is None else error) for name, error in checks.items()}
    shown["broker"] = broker_shown
    degraded = broker_error is None and broker_shown != "ok"
    failed = any(error is not None for error in checks.values())
    result: dict[str, Any] = {
        "status": "error" if failed else ("degraded" if degraded else "ok"),
        "checks": shown,
    }
    if len(nodes) > 1:
        result["broker_nodes"] = {
            address: "ok" if error is None else error for address, error in nodes.items()
        }
    return result


def cached_checks(now: float | None = None) -> dict[str, Any]:
    """run_checks' result, reused for HEALTH_CACHE_S; one caller at a time refreshes it."""
    global _cached
    now = time.monotonic() if now is None else now
    with _lock:
        if _cached is None or now - _cached[0] >= settings.HEALTH_CACHE_S:
            _cached = (now, run_checks())
        return _cached[1]


def forget() -> None:
    """Drop the cached result: the next /health checks again."""
    global _cached
    with _lock:
        _cached = None


def health(request: HttpRequest) -> JsonResponse:
    result = cached_checks()
    code = 503 if result["status"] == "error" else 200
    if not request.user.is_staff:
        return JsonResponse({"status": result["status"]}, status=code)
    body = dict(result)
    if result["checks"]["redis"] == "ok":
        from workers.counters import snapshot

        body["processes"] = snapshot()
    return JsonResponse(body, status=code)

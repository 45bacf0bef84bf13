"""/health: is every part up? 200 when the database, Redis and the broker answer, else 503."""

from __future__ import annotations

import time
from urllib.parse import urlsplit

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


def check_broker(timeout: float = 2.0) -> str | None:
    """A real MQTT CONNECT with the ground's credentials."""
    url = urlsplit(settings.MQTT_URL)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="", clean_session=True)
    if url.username:
        client.username_pw_set(url.username, url.password)
    result: dict[str, object] = {}
    client.on_connect = lambda c, u, f, rc, p: result.setdefault("rc", rc)
    try:
        client.connect(url.hostname or "127.0.0.1", url.port or 1883, keepalive=5)
    except OSError as exc:
        return str(exc)
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


def health(request: HttpRequest) -> JsonResponse:
    checks = {"database": check_database(), "redis": check_redis(), "broker": check_broker()}
    body: dict[str, object] = {
        "status": "ok" if not any(checks.values()) else "error",
        "checks": {name: ("ok" if error is None else error) for name, error in checks.items()},
    }
    if checks["redis"] is None:
        from workers.counters import snapshot

        body["processes"] = snapshot()
    return JsonResponse(body, status=200 if body["status"] == "ok" else 503)

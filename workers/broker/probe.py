"""Is a broker node up? A real MQTT CONNECT with the ground's credentials, and its answer."""

from __future__ import annotations

import time
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as mqtt

from onboard.mqtt import secure


def connect_error(url: str, timeout: float = 2.0) -> str | None:
    """Why the node at `url` does not accept the ground's connection (None: it does)."""
    parts = urlsplit(url)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="", clean_session=True)
    if parts.username:
        client.username_pw_set(unquote(parts.username), unquote(parts.password or ""))
    secure(client, parts.scheme == "mqtts")
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

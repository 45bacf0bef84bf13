"""A private broker wired to the settings, and an in-process gateway on it."""

from __future__ import annotations

import uuid

import pytest

from tests.support.mosquitto import start_broker

GROUND_PASSWORD = "ground-test-password"


@pytest.fixture
def broker(tmp_path, settings):  # type: ignore[no-untyped-def]
    """Mosquitto with only the ground user; provision drones into it with fleet.credentials."""
    directory = tmp_path / "mosquitto"
    b = start_broker(
        directory,
        {"ground": GROUND_PASSWORD},
        extra_config=f"pid_file {directory / 'mosquitto.pid'}\n",
    )
    settings.MOSQUITTO_DIR = str(directory)
    settings.MQTT_URL = b.url_for("ground")
    settings.MQTT_PUBLIC_HOST = "127.0.0.1"
    settings.MQTT_PUBLIC_PORT = b.port
    yield b
    b.stop()


@pytest.fixture
def fresh_redis():  # type: ignore[no-untyped-def]
    """No outbox left over from an earlier run."""
    from fleet import link

    link.sync_redis().delete(link.OUTBOX_KEY)
    return link.sync_redis()


@pytest.fixture
def gateway(broker, fresh_redis):  # type: ignore[no-untyped-def]
    from workers.counters import Counters
    from workers.gateway import Gateway

    gw = Gateway(
        broker.url_for("ground"),
        client_id=f"gw-{uuid.uuid4().hex[:8]}",
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gw.start()
    assert gw.wait_connected(10)
    yield gw
    gw.stop()


def mqtt_client(url: str, client_id: str | None = None):  # type: ignore[no-untyped-def]
    """A connected paho client (VERSION2, TCP_NODELAY), or the refusal reason as an error."""
    import socket
    import threading
    from urllib.parse import urlsplit

    import paho.mqtt.client as mqtt

    parts = urlsplit(url)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id or uuid.uuid4().hex)
    client.username_pw_set(parts.username, parts.password)
    done = threading.Event()
    outcome: dict = {}

    def on_connect(c, userdata, flags, reason_code, properties):  # type: ignore[no-untyped-def]
        outcome["rc"] = reason_code
        if not reason_code.is_failure:
            c.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        done.set()

    client.on_connect = on_connect
    client.connect(parts.hostname, parts.port)
    client.loop_start()
    done.wait(5)
    if "rc" not in outcome or outcome["rc"].is_failure:
        client.loop_stop()
        raise ConnectionRefusedError(str(outcome.get("rc")))
    return client


def heartbeat(drone_id: str, **overrides: object) -> dict:
    import time

    message = {
        "type": "heartbeat",
        "drone_id": drone_id,
        "ts": time.time(),
        "position": {"lat": 40.6303, "lon": -8.6575, "alt": 12.0},
        "battery": {"voltage": 16.4, "remaining": 0.9},
        "armed": True,
        "airborne": True,
        "flight_mode": "POSITIONHOLD",
        "mission": None,
        "fc": {"protocol": "uavtalk", "connected": True},
    }
    message.update(overrides)
    return message


def wait_for(predicate, timeout: float = 5.0, interval: float = 0.02):  # type: ignore[no-untyped-def]
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    return predicate()

"""A private broker wired to the settings, and an in-process gateway on it."""

from __future__ import annotations

import uuid

import pytest

from workers.mosquitto import start_broker

GROUND_PASSWORD = "ground-test-password"


@pytest.fixture(scope="session")
def _shared_broker(tmp_path_factory):  # type: ignore[no-untyped-def]
    directory = tmp_path_factory.mktemp("ground") / "mosquitto"
    b = start_broker(
        directory,
        {"ground": GROUND_PASSWORD},
        extra_config=f"pid_file {directory / 'mosquitto.pid'}\n",
    )
    yield b
    b.stop()


@pytest.fixture
def broker(_shared_broker, settings):  # type: ignore[no-untyped-def]
    """Mosquitto with the ground user, wired to the settings; provision drones into it with
    fleet.credentials (its passwd and ACL are regenerated from each test's database)."""
    b = _shared_broker
    if b.process is None or b.process.poll() is not None:
        b.start()
    settings.MOSQUITTO_DIR = str(b.directory)
    settings.MQTT_URL = b.url_for("ground")
    settings.MQTT_PUBLIC_HOST = "127.0.0.1"
    settings.MQTT_PUBLIC_PORT = b.port
    return b


@pytest.fixture
def fresh_redis(broker):  # type: ignore[no-untyped-def]
    """No outbox left over from an earlier run."""
    from workers import outbox

    outbox.sync_redis().delete(outbox.outbox_key(broker.url))
    return outbox.sync_redis()


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


def subscribe_acked(client, topics: str | list[tuple[str, int]], timeout: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    """Subscribe (QoS 1 for a single topic) and return once the broker has acknowledged it:
    a message published before then is not delivered to this client. A whole request and
    reply through Mosquitto takes 0.6-1.2 ms here (bare MQTT p50, bench.bench_ground);
    10 s is for a loaded machine."""
    import threading

    acked: dict[int, list] = {}
    arrived = threading.Condition()

    def on_subscribe(c, userdata, mid, reason_codes, properties):  # type: ignore[no-untyped-def]
        with arrived:
            acked[mid] = reason_codes
            arrived.notify_all()

    client.on_subscribe = on_subscribe
    _, mid = (
        client.subscribe(topics, qos=1) if isinstance(topics, str) else client.subscribe(topics)
    )
    with arrived:
        assert arrived.wait_for(lambda: mid in acked, timeout), f"no SUBACK for {topics}"
    refused = [code for code in acked[mid] if code.is_failure]
    assert not refused, f"subscription to {topics} refused: {refused}"


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


class Responder:
    """A minimal MQTT drone: answers `<id>/control/in` the way the agent does (used where
    the test is about the ground side; the end-to-end tests run the real agent)."""

    def __init__(
        self, url: str, drone_id: str, *, refuse: tuple[str, ...] = (), delay: float = 0.0
    ) -> None:
        import json
        import threading
        import time

        self.drone_id = drone_id
        self.requests: list[dict] = []
        self.missions: list[dict] = []
        self.client = mqtt_client(url)

        def on_message(client, userdata, message):  # type: ignore[no-untyped-def]
            request = json.loads(message.payload)
            if message.topic.endswith("/mission/in"):
                self.missions.append(request)
                return
            self.requests.append(request)
            ok = request["command"] not in refuse
            reply = {
                "request_id": request["request_id"],
                "command": request["command"],
                "ok": ok,
                "result": {"echo": request["params"]} if ok else None,
                "error": None if ok else "refused by the test drone",
                "ts": time.time(),
            }
            answer = (f"{drone_id}/control/out", json.dumps(reply))
            if delay:
                threading.Timer(delay, client.publish, answer, {"qos": 1}).start()
            else:
                client.publish(*answer, qos=1)

        self.client.on_message = on_message
        subscribe_acked(self.client, [(f"{drone_id}/control/in", 1), (f"{drone_id}/mission/in", 1)])

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def _threaded_client_class():  # type: ignore[no-untyped-def]
    from concurrent.futures import ThreadPoolExecutor

    from django.db import connections
    from django.test import Client

    class ThreadedClient(Client):
        """Django's test client with each request on a worker thread.

        Async views run through async_to_sync, which refuses a thread where an event loop
        runs, and Playwright's sync API keeps one in the main thread for the rest of the
        session once any browser test has run.
        """

        def request(self, **request):  # type: ignore[no-untyped-def]
            def run():  # type: ignore[no-untyped-def]
                try:
                    return Client.request(self, **request)
                finally:
                    connections.close_all()

            with ThreadPoolExecutor(1) as pool:
                return pool.submit(run).result()

    return ThreadedClient


def client_for(user=None):  # type: ignore[no-untyped-def]
    """A test client logged in as `user` (anonymous when None)."""
    client = _threaded_client_class()()
    if user is not None:
        client.force_login(user)
    return client


def drone_url(broker, drone_id: str) -> str:  # type: ignore[no-untyped-def]
    """A drone's own broker URL (its credentials provisioned in the test's database)."""
    from fleet import credentials
    from fleet.models import Drone

    organisation = Drone.objects.get(drone_id=drone_id).organisation.slug
    creds = credentials.provision(drone_id, organisation)
    return f"mqtt://{drone_id}:{creds.password}@127.0.0.1:{broker.port}"


@pytest.fixture
def ready_link(broker):  # type: ignore[no-untyped-def]
    """This process's connection to the test broker, subscribed and ready."""
    from workers import direct

    direct.close()
    link = direct.link()
    assert link is not None and link.ready.wait(10)
    yield link
    direct.close()


@pytest.fixture
def responding_drone(world_tx, broker):  # type: ignore[no-untyped-def]
    """ACME_1 online and answering its commands (a Responder on its own account)."""
    from fleet.models import Drone

    Drone.objects.filter(drone_id="ACME_1").update(online=True)
    responder = Responder(drone_url(broker, "ACME_1"), "ACME_1")
    yield responder
    responder.stop()

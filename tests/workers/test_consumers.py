"""Competing consumers on a real two-node RabbitMQ cluster.

Drones are real RabbitMQ users (fleet.credentials) publishing over MQTT to either node;
the gateways and ingests read the shared AMQP queues. Each message must be handled by
exactly one of two consumers, and commands must reach a drone whichever node it is on.
"""

from __future__ import annotations

import json
import socket
import threading
import time
import urllib.error
import uuid
from collections.abc import Iterator
from contextlib import ExitStack
from typing import Any

import paho.mqtt.client as mqtt
import psycopg
import pytest

from fleet import credentials
from runtime.processes import wait_for
from telemetry.ingest import CounterSink, DroneMap, IngestConfig, Ingestor, load_drone_ids
from workers import broker, outbox
from workers.counters import Counters
from workers.gateway import Gateway

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# What the recording dispatch saw: (drone id, heartbeat ts), from every gateway's threads.
SEEN: list[tuple[str, float]] = []
SEEN_LOCK = threading.Lock()
RECORDING = {"heartbeats": "tests.workers.test_consumers.record_heartbeat"}


def record_heartbeat(drone_id: str, message: Any) -> None:
    with SEEN_LOCK:
        SEEN.append((drone_id, message.ts))


# -- helpers shared with test_failover ------------------------------------------------------


def purge(cluster: Any, queue: str) -> None:
    try:
        cluster.api("DELETE", f"queues/%2F/{queue}/contents")
    except urllib.error.HTTPError as exc:
        if exc.code != 404:  # not declared yet: nothing to purge
            raise


@pytest.fixture
def cleanup() -> Iterator[ExitStack]:
    """Stops what a test started, in reverse order, even when it fails half-way."""
    with ExitStack() as stack:
        yield stack


def use_cluster(cluster: Any, settings: Any) -> Any:
    """Point the settings at the test cluster; empty its shared queues and the outbox."""
    settings.MQTT_BROKER = "rabbitmq"
    settings.MQTT_URL = cluster.mqtt_urls[0]
    settings.MQTT_URLS = cluster.mqtt_urls
    settings.AMQP_URLS = cluster.amqp_urls
    settings.RABBITMQ_API_URLS = cluster.api_urls
    settings.MQTT_PUBLIC_HOST = "127.0.0.1"
    for group in ("gateway", "ingest"):
        purge(cluster, f"skyhive.{group}")
    outbox.sync_redis().delete(outbox.outbox_key())
    return cluster


@pytest.fixture
def on_cluster(rabbit_cluster, settings) -> Any:  # type: ignore[no-untyped-def]
    """The settings of a ground on the test cluster."""
    return use_cluster(rabbit_cluster, settings)


def node_url(creds: credentials.Credentials, node: int) -> str:
    """The drone's own URL for node `node` (1-based) of the cluster."""
    return creds.urls[node - 1]


class Drone:
    """A drone's MQTT connection to one node: publishes, and records what it is sent.

    A drone account logs in only under the client ids drones use (its id, or the agent's
    `skyhive-agent-<id>`); a ground connection takes any id of its own."""

    def __init__(self, url: str, drone_id: str, *, client_id: str | None = None) -> None:
        from urllib.parse import unquote, urlsplit

        parts = urlsplit(url)
        self.drone_id = drone_id
        self.inbox: list[dict] = []
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=client_id or uuid.uuid4().hex
        )
        self.client.username_pw_set(unquote(parts.username or ""), unquote(parts.password or ""))
        connected = threading.Event()
        self.client.on_connect = lambda c, u, f, rc, p: rc.is_failure or connected.set()
        self.client.on_message = lambda c, u, m: self.inbox.append(_decoded(m.payload))
        self.client.connect(parts.hostname, parts.port)
        self.client.loop_start()
        assert connected.wait(10), f"{drone_id} could not connect to {parts.port}"

    def subscribe_inbox(self, channel: str = "control") -> None:
        done = threading.Event()
        self.client.on_subscribe = lambda *args: done.set()
        self.client.subscribe(f"{self.drone_id}/{channel}/in", qos=1)
        assert done.wait(5)

    def publish(self, channel: str, message: dict, qos: int = 1) -> None:
        info = self.client.publish(f"{self.drone_id}/{channel}/out", json.dumps(message), qos=qos)
        info.wait_for_publish(10)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def _decoded(payload: bytes) -> Any:
    try:
        return json.loads(payload)
    except ValueError:
        return payload


def heartbeat(drone_id: str, ts: float) -> dict:
    return {
        "type": "heartbeat",
        "drone_id": drone_id,
        "ts": ts,
        "position": {"lat": 40.6303, "lon": -8.6575, "alt": 12.0},
        "battery": {"voltage": 16.4, "remaining": 0.9},
        "armed": False,
        "airborne": False,
        "flight_mode": "MANUAL",
        "mission": None,
        "fc": {"protocol": "uavtalk", "connected": True},
    }


def telemetry(i: int, start: float) -> dict:
    ts = start + i * 0.01
    return {"ts": ts, "objects": [{"name": "Gyros", "ts": ts, "fields": {"x": i, "y": 0.5}}]}


def recording_gateway(name: str, first_node: int, cluster: Any) -> Gateway:
    """A gateway whose dispatch records heartbeats, on node `first_node` first (started;
    stop it, with `started`)."""
    order = [first_node - 1] + [i for i in range(len(cluster.mqtt_urls)) if i != first_node - 1]
    gateway = Gateway(
        [cluster.mqtt_urls[i] for i in order],
        amqp_urls=[cluster.amqp_urls[i] for i in order],
        dispatch=RECORDING,
        batch_dispatch={},
        client_id=f"{name}-{uuid.uuid4().hex[:6]}",
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gateway.start()
    if not gateway.wait_connected(15):
        gateway.stop()
        raise AssertionError(f"{name} did not connect")
    return gateway


def started(stack: ExitStack, thing: Any) -> Any:
    """Register a gateway, drone or consumer to be stopped when the test ends."""
    stack.callback(thing.close if isinstance(thing, Drone) else thing.stop)
    return thing


def ingestor(stack: ExitStack, first_node: int, cluster: Any) -> tuple[Ingestor, CounterSink]:
    from telemetry.queries import conninfo_from_settings

    conninfo = conninfo_from_settings()
    urls = list(cluster.amqp_urls)
    urls = urls[first_node - 1 :] + urls[: first_node - 1]
    counters = CounterSink()
    ingest = Ingestor(
        IngestConfig(conninfo=conninfo, mqtt_url="", amqp_urls=urls, flush_interval=0.05),
        drones=DroneMap(lambda: load_drone_ids(conninfo)),
        counters=counters,
    )
    ingest.start()
    stack.callback(ingest.stop)
    assert ingest.subscriber.subscribed.wait(15)
    return ingest, counters


def stored(drone_pk: int) -> tuple[int, int]:
    """(rows, distinct (object, ts)) stored for a drone."""
    from telemetry.queries import conninfo_from_settings

    with psycopg.connect(conninfo_from_settings()) as conn:
        return conn.execute(
            "SELECT count(*), count(DISTINCT (object, ts)) FROM telemetry_sample "
            "WHERE drone_id = %s",
            (drone_pk,),
        ).fetchone()


# -- pure pieces ----------------------------------------------------------------------------


def test_mqtt_topics_and_amqp_routing_keys_translate_both_ways():
    assert broker.routing_key("+/telemetry/out") == "*.telemetry.out"
    assert broker.routing_key("ACME_1/heartbeats/out") == "ACME_1.heartbeats.out"
    assert broker.topic_of("ACME_1.heartbeats.out") == "ACME_1/heartbeats/out"


def test_every_node_of_the_cluster_shares_one_outbox_and_is_tried_after_the_one_named(settings):
    settings.MQTT_URL = "mqtt://ground:pw@127.0.0.1:19101"
    settings.MQTT_URLS = ["mqtt://ground:pw@127.0.0.1:19101", "mqtt://ground:pw@127.0.0.1:19102"]
    assert outbox.outbox_key("mqtt://other:x@127.0.0.1:19102") == outbox.outbox_key()
    assert outbox.outbox_key("mqtt://ground:pw@127.0.0.1:1883") != outbox.outbox_key()
    assert broker.cluster_urls("mqtt://ground:pw@127.0.0.1:19102") == [
        "mqtt://ground:pw@127.0.0.1:19102",
        "mqtt://ground:pw@127.0.0.1:19101",
    ]
    assert broker.cluster_urls("mqtt://elsewhere:1883") == ["mqtt://elsewhere:1883"]


# -- on the cluster -------------------------------------------------------------------------


def test_two_gateways_on_different_nodes_handle_every_drone_message_exactly_once(
    world_tx, on_cluster, cleanup
):
    cluster = on_cluster
    first = credentials.provision("ACME_1")
    second = credentials.provision("GLOBEX_1")
    gateways = [
        started(cleanup, recording_gateway("gw-a", 1, cluster)),
        started(cleanup, recording_gateway("gw-b", 2, cluster)),
    ]
    drones = [
        started(cleanup, Drone(node_url(first, 1), "ACME_1", client_id="ACME_1")),
        started(cleanup, Drone(node_url(second, 2), "GLOBEX_1", client_id="GLOBEX_1")),
    ]
    SEEN.clear()
    start = time.time()
    sent = []
    for i in range(150):
        for drone in drones:
            ts = start + i * 0.001
            drone.publish("heartbeats", heartbeat(drone.drone_id, ts), qos=1)
            sent.append((drone.drone_id, ts))
    assert wait_for(lambda: len(SEEN) >= len(sent), 20), f"{len(SEEN)} of {len(sent)}"
    time.sleep(0.3)  # a duplicate would arrive now
    assert sorted(SEEN) == sorted(sent)
    handled = [g.counters.get("handled") for g in gateways]
    assert sum(handled) == len(sent) and all(handled), handled


def test_a_command_reaches_a_drone_on_either_node_once_whichever_gateway_sends_it(
    world_tx, on_cluster, cleanup
):
    cluster = on_cluster
    creds = credentials.provision("ACME_1")
    gateways = [
        started(cleanup, recording_gateway("gw-a", 1, cluster)),
        started(cleanup, recording_gateway("gw-b", 2, cluster)),
    ]
    assert gateways[0].outbox == gateways[1].outbox == outbox.outbox_key()
    drone = started(cleanup, Drone(node_url(creds, 2), "ACME_1", client_id="ACME_1"))
    drone.subscribe_inbox()
    for n in range(20):
        outbox.send_to_drone("ACME_1", "control", {"n": n}, ttl=30)
    assert wait_for(lambda: len(drone.inbox) >= 20, 10), drone.inbox
    time.sleep(0.3)
    assert sorted(m["n"] for m in drone.inbox) == list(range(20))
    published = [g.counters.get("published") for g in gateways]
    assert sum(published) == 20


def test_two_ingests_store_every_telemetry_sample_exactly_once(world_tx, on_cluster, cleanup):
    cluster = on_cluster
    creds = credentials.provision("ACME_1")
    ingests = [ingestor(cleanup, 1, cluster), ingestor(cleanup, 2, cluster)]
    drones = [
        started(cleanup, Drone(node_url(creds, 1), "ACME_1", client_id="ACME_1")),
        started(cleanup, Drone(node_url(creds, 2), "ACME_1", client_id="skyhive-agent-ACME_1")),
    ]
    start = time.time() - 60
    for i in range(600):
        drones[i % 2].publish("telemetry", telemetry(i, start), qos=1)
    assert wait_for(lambda: stored(world_tx.drone.pk)[0] >= 600, 20)
    time.sleep(0.5)  # a duplicate would be written now
    assert stored(world_tx.drone.pk) == (600, 600)
    taken = [counters.counts.get("objects_received", 0) for _, counters in ingests]
    assert sum(taken) == 600 and all(taken), taken


def test_a_consumer_counts_and_survives_messages_its_callback_cannot_take(on_cluster):
    cluster = on_cluster
    taken: list[str] = []

    def fussy(topic: str, payload: bytes) -> None:
        if payload == b"boom":
            raise ValueError("a bug in a handler")
        taken.append(topic)

    counters = CounterSink()
    consumer = broker.AmqpConsumer(
        "gateway", ["gear"], fussy, urls=cluster.amqp_urls, counters=counters
    )
    consumer.start()
    assert consumer.subscribed.wait(10)
    ground = Drone(cluster.mqtt_urls[0], "ACME_1")
    try:
        for payload in (b"boom", b"{}", b"boom", b"{}"):
            ground.client.publish("ACME_1/gear/out", payload, qos=1).wait_for_publish(5)
        assert wait_for(lambda: len(taken) == 2, 10)
        assert taken == ["ACME_1/gear/out", "ACME_1/gear/out"]
        assert counters.counts["amqp.callback_errors"] == 2
        assert consumer.subscribed.is_set() and consumer.sessions == 1
    finally:
        ground.close()
        consumer.stop()
    # Everything was acknowledged: nothing waits in the queue for the next consumer.
    # (A new queue has no message counts until the management API's next 5 s refresh.)
    queue = cluster.api("GET", "queues/%2F/skyhive.gateway")
    assert wait_for(
        lambda: cluster.api("GET", "queues/%2F/skyhive.gateway").get("messages") == 0, 15
    )
    assert queue["durable"]


def test_messages_held_by_a_consumer_that_dies_are_redelivered_to_its_peer(on_cluster, cleanup):
    cluster = on_cluster
    held = threading.Event()
    release = threading.Event()
    peer_got: list[str] = []

    def stuck(topic: str, payload: bytes) -> None:
        held.set()
        release.wait(10)  # a process hung or dying with the message in hand: never acked

    dying = started(
        cleanup, broker.AmqpConsumer("gateway", ["gear"], stuck, urls=cluster.amqp_urls[:1])
    )
    cleanup.callback(release.set)  # runs first: lets the stuck thread end
    dying.start()
    assert dying.subscribed.wait(10)
    ground = started(cleanup, Drone(cluster.mqtt_urls[0], "ACME_1"))
    for n in range(20):
        ground.client.publish("ACME_1/gear/out", str(n), qos=1).wait_for_publish(5)
    assert held.wait(10)
    peer = started(
        cleanup,
        broker.AmqpConsumer(
            "gateway",
            ["gear"],
            lambda topic, payload: peer_got.append(payload.decode()),
            urls=cluster.amqp_urls[1:],
        ),
    )
    peer.start()
    assert peer.subscribed.wait(10)
    # The dying consumer's connection drops without a word, as on kill -9.
    dying._conn.sock.shutdown(socket.SHUT_RDWR)  # noqa: SLF001
    assert wait_for(lambda: sorted(peer_got, key=int) == [str(n) for n in range(20)], 15)
    assert peer.redelivered >= 1

"""A RabbitMQ node killed under the ground and the drones.

The test kills (kill -9) the node a gateway, an ingest and a drone's agent link are
connected to while the other node stays up, then checks that they moved there on their
own and that nothing published meanwhile or afterwards was lost. The killed node is
started again after the test.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack
from typing import Any

import pytest

from fleet import credentials
from onboard.mqtt import MqttLink
from runtime.processes import wait_for
from workers import outbox
from workers.mosquitto import start_broker

from .test_consumers import (
    SEEN,
    Drone,
    heartbeat,
    ingestor,
    node_url,
    recording_gateway,
    started,
    stored,
    telemetry,
    use_cluster,
)

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def node_2_restarted_after(rabbit_cluster, settings) -> Iterator[Any]:  # type: ignore[no-untyped-def]
    """The cluster, the settings on it; node 2 is started again after the test (it kills it)."""
    yield use_cluster(rabbit_cluster, settings)
    rabbit_cluster.start_node(2)


@pytest.fixture
def cleanup() -> Iterator[ExitStack]:
    with ExitStack() as stack:
        yield stack


def test_a_killed_node_moves_the_gateway_ingest_and_drone_links_to_the_other_losing_nothing(
    world_tx, node_2_restarted_after, cleanup
):
    # One kill for all three clients: a node takes long to start again on a busy machine.
    cluster = node_2_restarted_after
    creds = credentials.provision("ACME_1")
    # On node 2, to be killed: a gateway, an ingest, and the agent's link of drone ACME_1.
    gateway = started(cleanup, recording_gateway("gw", 2, cluster))
    ingest, _ = ingestor(cleanup, 2, cluster)
    agent_inbox: list[bytes] = []
    lock = threading.Lock()

    def on_message(topic: str, payload: bytes) -> None:
        with lock:
            agent_inbox.append(payload)

    agent = MqttLink(
        f"{node_url(creds, 2)},{node_url(creds, 1)}",  # as `--broker` takes a cluster
        client_id="skyhive-agent-ACME_1",
        subscriptions=["ACME_1/control/in"],
        on_message=on_message,
    )
    agent.start()
    cleanup.callback(agent.stop, flush_timeout=0)
    assert agent.wait_connected(10) and agent.broker.port == cluster.mqtt_port(2)
    # On node 1, which stays up: another drone's link (a publisher as the drone's user)
    # and a ground client sending to the agent's inbox.
    drone = started(cleanup, Drone(node_url(creds, 1), "ACME_1", client_id="ACME_1"))
    drone.subscribe_inbox("mission")
    ground = started(cleanup, Drone(cluster.mqtt_urls[0], "ground"))

    def to_agent(text: str) -> None:
        ground.client.publish("ACME_1/control/in", text, qos=1).wait_for_publish(5)

    # Once the agent's subscription is in place a message gets through; then start afresh.
    assert wait_for(lambda: to_agent("hello") or agent_inbox, 10, interval=0.5)
    time.sleep(0.3)
    agent_inbox.clear()

    SEEN.clear()
    start = time.time()
    sent: list[tuple[str, float]] = []

    def fly(first: int, count: int) -> None:
        for i in range(first, first + count):
            ts = start + i * 0.001
            drone.publish("heartbeats", heartbeat("ACME_1", ts), qos=1)
            drone.publish("telemetry", telemetry(i, start - 60), qos=1)
            sent.append(("ACME_1", ts))

    fly(0, 50)
    assert wait_for(lambda: len(SEEN) >= 50 and stored(world_tx.drone.pk)[0] >= 50, 10)
    time.sleep(0.2)  # acknowledgements are batched: let them reach the node

    # Hold the agent away until the ground's messages wait in its session: its network
    # thread stops once it has seen the node go (a reconnect delay of a minute, which the
    # stop cuts short, keeps it from coming back first) and starts again after the queueing,
    # however long a loaded machine takes over it.
    agent.client.reconnect_delay_set(min_delay=60, max_delay=60)
    cluster.kill_node(2)
    assert wait_for(lambda: not agent.connected, 5)
    agent.client.loop_stop()
    fly(50, 50)  # while the ground is still failing over: queued on node 1's mirror
    for n in range(10):
        to_agent(f"while away {n}")
    agent.client.reconnect_delay_set(min_delay=0.1, max_delay=1)
    agent.client.loop_start()

    assert wait_for(lambda: gateway.consumer.sessions == 2 and ingest.subscriber.sessions == 2)
    assert wait_for(lambda: gateway.connected.is_set() and gateway.port == cluster.mqtt_port(1))
    fly(100, 50)

    # The ground: every message once, every sample stored once, commands still go out.
    assert wait_for(lambda: len(SEEN) >= 150 and stored(world_tx.drone.pk)[0] >= 150, 20)
    time.sleep(0.3)
    assert sorted(SEEN) == sorted(sent)
    assert stored(world_tx.drone.pk) == (150, 150)
    outbox.send_to_drone("ACME_1", "mission", {"after": "failover"}, ttl=30)
    assert wait_for(lambda: drone.inbox == [{"after": "failover"}], 10)

    # The agent: on node 1 now, with everything sent to it while it was away.
    assert wait_for(lambda: agent.connected and agent.broker.port == cluster.mqtt_port(1), 15)
    expected = [f"while away {n}".encode() for n in range(10)]
    assert wait_for(lambda: sorted(agent_inbox) == sorted(expected), 10), agent_inbox
    assert agent.failover.switches == 1
    agent.publish("ACME_1/gear/out", b"{}", qos=1)
    assert agent.flush(5)


def test_a_link_given_several_brokers_moves_on_when_its_broker_stops_and_a_connect_fails(tmp_path):
    # Plain Mosquitto brokers: the failover itself, without RabbitMQ's shared sessions.
    first = start_broker(tmp_path / "a", {"DRONE1": "pw"})
    second = start_broker(tmp_path / "b", {"DRONE1": "pw"})
    received: list[bytes] = []
    agent = MqttLink(
        f"{first.url_for('DRONE1')},{second.url_for('DRONE1')}",
        client_id="skyhive-agent-DRONE1",
        subscriptions=["DRONE1/control/in"],
        on_message=lambda topic, payload: received.append(payload),
    )
    try:
        agent.start()
        assert agent.wait_connected(10) and agent.broker.port == first.port
        first.stop()
        assert wait_for(lambda: agent.connected and agent.broker.port == second.port, 10)
        second.stop()  # nowhere to go: it keeps trying both, never raising
        assert wait_for(lambda: not agent.connected, 5)
        first.start()
        assert wait_for(lambda: agent.connected and agent.broker.port == first.port, 15)
        assert agent.failover.switches >= 2
    finally:
        agent.stop(flush_timeout=0)
        first.stop()
        second.stop()

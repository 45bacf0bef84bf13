"""The broker package's plain subscription (workers.broker.client.Listener), as the past
view uses it, on real Mosquitto brokers: every message of its topics, and the next node
when one does not answer."""

from __future__ import annotations

import queue
import time
from pathlib import Path

import paho.mqtt.client as paho
import pytest

from runtime.processes import free_port
from workers.broker.client import Listener
from workers.mosquitto import start_broker


@pytest.fixture
def broker(tmp_path: Path):  # type: ignore[no-untyped-def]
    b = start_broker(tmp_path, {"ground": "gpw", "ACME_1": "dpw"})
    yield b
    b.stop()


def _publish(broker, topic: str, payload: bytes) -> None:  # type: ignore[no-untyped-def]
    drone = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id="test-drone")
    drone.username_pw_set("ACME_1", "dpw")
    drone.connect("127.0.0.1", broker.port, keepalive=10)
    drone.loop_start()
    try:
        drone.publish(topic, payload, qos=1).wait_for_publish(5)
    finally:
        drone.disconnect()
        drone.loop_stop()


def _listen(urls: list[str], topics: list[str]) -> tuple[Listener, queue.Queue]:
    received: queue.Queue = queue.Queue()
    listener = Listener(
        urls, f"test-listener-{time.monotonic_ns()}", topics, lambda t, p: received.put((t, p))
    )
    listener.start()
    return listener, received


def test_a_listener_hands_over_every_message_of_its_topics_and_no_other(broker):
    listener, received = _listen([broker.url_for("ground")], ["+/camera/out", "+/telemetry/out"])
    try:
        assert listener.subscribed.wait(10), "the listener did not subscribe"
        _publish(broker, "ACME_1/alarms/out", b"not listened to")
        _publish(broker, "ACME_1/camera/out", b"a frame")
        _publish(broker, "ACME_1/telemetry/out", b"a pose")
        got = [received.get(timeout=5), received.get(timeout=5)]
    finally:
        listener.stop()
    assert got == [("ACME_1/camera/out", b"a frame"), ("ACME_1/telemetry/out", b"a pose")]
    assert received.empty()


def test_a_listener_moves_to_the_next_node_when_the_first_does_not_answer(broker):
    dead = f"mqtt://ground:gpw@127.0.0.1:{free_port()}"  # nothing listens there
    listener, received = _listen([dead, broker.url_for("ground")], ["+/camera/out"])
    try:
        assert listener.subscribed.wait(15), "the listener did not reach the second node"
        assert listener.failover.current.port == broker.port
        _publish(broker, "ACME_1/camera/out", b"a frame")
        assert received.get(timeout=5) == ("ACME_1/camera/out", b"a frame")
    finally:
        listener.stop()

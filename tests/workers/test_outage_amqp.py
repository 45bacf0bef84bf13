"""On RabbitMQ, a consumer with manual acknowledgement acknowledges only what its owner
settled: a message still in hand (a gateway lane retrying through an outage) stays
unacknowledged while later ones are acknowledged around it, and goes to a peer when the
consumer dies."""

from __future__ import annotations

import socket
import threading

import pytest

from runtime.processes import wait_for
from workers import broker
from workers.broker.amqp import STRAGGLER_ACK_S

from .test_consumers import Drone, cleanup, on_cluster, started  # noqa: F401 - fixtures

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

HELD = "3"


def test_only_settled_messages_are_acknowledged_and_the_one_in_hand_goes_to_a_peer(
    on_cluster,  # noqa: F811
    cleanup,  # noqa: F811
):
    cluster = on_cluster
    seen: list[str] = []
    lock = threading.Lock()

    def settle_all_but_one(topic: str, payload: bytes, settle) -> None:  # type: ignore[no-untyped-def]
        with lock:
            seen.append(payload.decode())
        if payload.decode() != HELD:
            settle()

    first = started(
        cleanup,
        broker.AmqpConsumer(
            "gateway", ["gear"], settle_all_but_one, urls=cluster.amqp_urls[:1], manual_ack=True
        ),
    )
    first.start()
    assert first.subscribed.wait(10)
    ground = started(cleanup, Drone(cluster.mqtt_urls[0], "ACME_1"))
    for n in range(10):
        ground.client.publish("ACME_1/gear/out", str(n), qos=1).wait_for_publish(5)
    assert wait_for(lambda: len(seen) == 10, 10)

    def unacknowledged() -> int | None:
        queue = cluster.api("GET", "queues/%2F/skyhive.gateway")
        return queue.get("messages_unacknowledged")

    # The ones behind the held message are acknowledged after STRAGGLER_ACK_S; the
    # management API refreshes its counts every 5 s.
    assert wait_for(lambda: unacknowledged() == 1, STRAGGLER_ACK_S + 15, interval=0.5)
    peer_got: list[str] = []
    peer = started(
        cleanup,
        broker.AmqpConsumer(
            "gateway",
            ["gear"],
            lambda topic, payload, settle: (peer_got.append(payload.decode()), settle()),
            urls=cluster.amqp_urls[1:],
            manual_ack=True,
        ),
    )
    peer.start()
    assert peer.subscribed.wait(10)
    # The first consumer's connection drops without a word, as on kill -9.
    first._conn.sock.shutdown(socket.SHUT_RDWR)  # noqa: SLF001
    assert wait_for(lambda: peer_got == [HELD], 15), peer_got
    assert wait_for(lambda: unacknowledged() == 0 and peer_got == [HELD], 15, interval=0.5)

"""The ground's view of the broker: which nodes, failover, and competing consumers.

The package is the one place that knows which broker runs (settings.MQTT_BROKER): here the
nodes and the consumers; `credentials` its users and ACLs (Mosquitto's files, or RabbitMQ
users through `rabbitmq_admin`); `figures` and `mosquitto_sys` what the operations page
shows of it, `probe` whether a node accepts the ground's connection (/health); `amqp` and
`mqtt_reader` the two kinds of consumer; `client` the paho connection of the gateway, a web
process's direct link and the past view (no ground module outside this package imports paho).

Two brokers are supported (settings.MQTT_BROKER). Mosquitto is one node and shares the
drones' messages among several ground processes with MQTT shared subscriptions
(`$share/<group>/+/<channel>/out`). RabbitMQ 3.10's MQTT plugin grants such subscriptions
but delivers nothing to them, so there the competing consumers read a durable AMQP queue
`skyhive.<group>` bound to `amq.topic` (MQTT topic `A/b/c` is routing key `A.b.c`); the
`skyhive-ha` policy mirrors it on every node, and each consumer tries AMQP_URLS in turn.

Either way the consumer hands `(topic_with_slashes, payload_bytes)` to one callback and
acknowledges a message only after that callback returned, so a process that dies with
messages in hand gets them redelivered to its peers. With `manual_ack`, the callback gets
a third argument, `settle` (None for a QoS 0 delivery): the message is acknowledged only
once `settle()` is called, from any thread, so the gateway and the ingest acknowledge
what they have stored, not what they have read.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Protocol
from urllib.parse import urlsplit

from django.conf import settings

from onboard.mqtt import Failover, attach_failover
from workers.broker.mqtt_reader import Subscriber

from .amqp import AmqpConsumer, OnMessage, routing_key, topic_of

__all__ = [
    "AmqpConsumer",
    "Consumer",
    "Failover",
    "amqp_urls",
    "attach_failover",
    "cluster_urls",
    "competing_consumer",
    "mqtt_urls",
    "rabbitmq_api_urls",
    "routing_key",
    "same_node",
    "share_filter",
    "topic_of",
    "uses_amqp",
]


class Consumer(Protocol):
    """What the gateway and the ingest need of a competing consumer."""

    subscribed: threading.Event

    def start(self) -> None: ...

    def stop(self) -> None: ...


def uses_amqp() -> bool:
    """True when the ground reads the drones' messages from RabbitMQ queues over AMQP."""
    return settings.MQTT_BROKER == "rabbitmq"


def mqtt_urls() -> list[str]:
    """Every broker node's MQTT URL (the ground's credentials), in the order to try them."""
    return list(settings.MQTT_URLS) or [settings.MQTT_URL]


def amqp_urls() -> list[str]:
    return list(settings.AMQP_URLS)


def rabbitmq_api_urls() -> list[str]:
    """Every RabbitMQ node's management API (empty on Mosquitto)."""
    return list(settings.RABBITMQ_API_URLS) if uses_amqp() else []


def same_node(a: str, b: str) -> bool:
    """Two URLs of the same listener (host and port), whatever credentials they carry."""
    pa, pb = urlsplit(a), urlsplit(b)
    return (pa.hostname, pa.port or 1883) == (pb.hostname, pb.port or 1883)


def cluster_urls(url: str | Sequence[str] | None = None) -> list[str]:
    """The nodes a client given `url` should try: a list as given; one URL that is a node
    of MQTT_URLS first, then the other nodes; any other single URL alone."""
    if url is None:
        return mqtt_urls()
    if not isinstance(url, str):
        return list(url)
    if "," in url:
        return [u.strip() for u in url.split(",") if u.strip()]
    nodes = mqtt_urls()
    if any(same_node(url, node) for node in nodes):
        return [url, *(node for node in nodes if not same_node(url, node))]
    return [url]


def share_filter(group: str, channel: str) -> str:
    return f"$share/{group}/+/{channel}/out"


def competing_consumer(
    group: str,
    channels: Sequence[str],
    on_message: OnMessage,
    *,
    client_id: str,
    amqp_urls: Sequence[str] = (),
    mqtt_url: str = "",
    qos: int = 1,
    prefetch: int = 1000,
    counters: object | None = None,
    manual_ack: bool = False,
    on_messages: Callable[[list], object] | None = None,
) -> Consumer:
    """One member of consumer group `group` for the drones' `<id>/<channel>/out` messages.

    Given `amqp_urls` (RabbitMQ: `amqp_urls()` when `uses_amqp()`), an `AmqpConsumer` on
    `skyhive.<group>`; else an MQTT shared subscription on `mqtt_url` (one channel: the
    fast reader of workers.broker.mqtt_reader, which hands `on_messages`, when given,
    every message of one read at once). Needs no Django settings, so the ingest, which
    has none, builds its reader here too.
    """
    if amqp_urls:
        return AmqpConsumer(
            group,
            channels,
            on_message,
            urls=amqp_urls,
            prefetch=prefetch,
            name=client_id,
            counters=counters,
            manual_ack=manual_ack,
        )
    if len(channels) != 1:
        raise ValueError("the MQTT shared-subscription reader takes one channel")
    if not mqtt_url:
        raise ValueError("an MQTT shared subscription needs the broker's URL")
    return Subscriber(
        mqtt_url,
        client_id,
        share_filter(group, channels[0]),
        on_message,
        qos=qos,
        manual_ack=manual_ack,
        on_messages=on_messages,
    )

"""The ground's paho clients: built here, so no other ground module imports paho.

`ground_client` makes the one kind of connection every long-lived ground process holds
(the gateway, a web process's direct link, the past view): paho 2 callbacks, the given
client id and session, and the nodes of `urls` tried in turn (`attach_failover`: the
URL's credentials, TLS for mqtts://). `Listener` is the plain (not shared) subscription a
process takes when every message on some topics must reach it, rather than one member of
a group (`competing_consumer`). `publish_outcome` reads what a publish call answered.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from enum import Enum

import paho.mqtt.client as mqtt

from onboard.mqtt import Failover, attach_failover

log = logging.getLogger(__name__)

Client = mqtt.Client
Message = mqtt.MQTTMessage
PublishInfo = mqtt.MQTTMessageInfo


class Published(Enum):
    """What a publish call answered: handed to the client, not sendable now, refused."""

    OK = "ok"
    NOT_NOW = "not_now"  # no connection, or the client's queue is full: try again
    FAILED = "failed"


def publish_outcome(info: PublishInfo) -> Published:
    if info.rc == mqtt.MQTT_ERR_SUCCESS:
        return Published.OK
    if info.rc in (mqtt.MQTT_ERR_NO_CONN, mqtt.MQTT_ERR_QUEUE_SIZE):
        return Published.NOT_NOW
    return Published.FAILED


def error_text(info: PublishInfo) -> str:
    return mqtt.error_string(info.rc)


def ground_client(
    client_id: str,
    urls: str | Sequence[str],
    *,
    clean_session: bool = True,
    manual_ack: bool = False,
    min_delay: float = 0.2,
    max_delay: float = 10,
    configure: Callable[[mqtt.Client], object] | None = None,
) -> tuple[mqtt.Client, Failover]:
    """A paho client on the first node of `urls`, moving on to the next when one goes.

    `configure` sets the caller's callbacks and limits before the failover wraps
    `on_disconnect` and `on_connect_fail` (it must see them to keep calling them).
    Reconnects start at `min_delay`, not paho's 1 s: a lost node should cost a fraction
    of a second. Start it with `connect(client, failover)`.
    """
    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=client_id,
        clean_session=clean_session,
        manual_ack=manual_ack,
    )
    client.reconnect_delay_set(min_delay=min_delay, max_delay=max_delay)  # type: ignore[arg-type]
    if configure is not None:
        configure(client)
    return client, attach_failover(client, urls)


def connect(client: mqtt.Client, failover: Failover, keepalive: int = 30) -> None:
    """Connect in the background: paho retries the first connection too, with backoff."""
    current = failover.current
    client.connect_async(current.host, current.port, keepalive=keepalive)
    client.loop_start()


def disconnect(client: mqtt.Client, failover: Failover) -> None:
    failover.stopping = True
    client.disconnect()
    client.loop_stop()


class Listener:
    """Every message on `topics` (plain subscriptions, clean session), handed to
    `on_message(topic, payload)` on paho's network thread; resubscribes after each
    reconnect. An exception from `on_message` is logged and the reading goes on."""

    def __init__(
        self,
        urls: str | Sequence[str],
        client_id: str,
        topics: Sequence[str],
        on_message: Callable[[str, bytes], object],
        *,
        qos: int = 0,
        name: str = "listener",
    ) -> None:
        self.topics = list(topics)
        self.qos = qos
        self.name = name
        self.on_message = on_message
        self.connected = threading.Event()
        self.subscribed = threading.Event()
        self.client, self.failover = ground_client(
            client_id, urls, min_delay=1, max_delay=30, configure=self._configure
        )

    def _configure(self, client: mqtt.Client) -> None:
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_subscribe = lambda *args: self.subscribed.set()
        client.on_message = self._on_message

    def start(self) -> None:
        connect(self.client, self.failover)

    def stop(self) -> None:
        disconnect(self.client, self.failover)

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        if reason_code.is_failure:
            log.error("%s: broker refused the connection: %s", self.name, reason_code)
            return
        client.subscribe([(topic, self.qos) for topic in self.topics])
        self.connected.set()
        node = self.failover.current
        log.info("%s: connected to %s:%s", self.name, node.host, node.port)

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        self.connected.clear()
        self.subscribed.clear()

    def _on_message(self, client, userdata, message: mqtt.MQTTMessage) -> None:  # type: ignore[no-untyped-def]
        try:
            self.on_message(message.topic, message.payload)
        except Exception:  # noqa: BLE001 - no message may stop the reading
            log.exception("%s: handling %s failed", self.name, message.topic)

"""Broker Client: one paho-mqtt 2 connection with reconnect, QoS 1 and an outbox.

Nothing published at QoS 1 is lost while the broker is away or restarting: paho keeps
every QoS 1 message until the broker's PUBACK, and resends unacknowledged ones after it
reconnects (in publish order). `pending` counts them. Subscriptions are renewed on every
connect, because a restarted broker without persistence has forgotten the session.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as paho
from paho.mqtt.enums import CallbackAPIVersion

log = logging.getLogger(__name__)

MessageHandler = Callable[[str, bytes], None]


@dataclass(frozen=True)
class BrokerUrl:
    host: str
    port: int
    username: str | None
    password: str | None
    tls: bool = False


def parse_broker_url(url: str) -> BrokerUrl:
    """`mqtt://user:pass@host:port` (or mqtts://) → BrokerUrl; credentials URL-decoded."""
    parts = urlsplit(url)
    if parts.scheme not in ("mqtt", "mqtts", "tcp"):
        raise ValueError(f"broker URL must start with mqtt:// or mqtts://, got {url!r}")
    if not parts.hostname:
        raise ValueError(f"broker URL has no host: {url!r}")
    tls = parts.scheme == "mqtts"
    return BrokerUrl(
        host=parts.hostname,
        port=parts.port or (8883 if tls else 1883),
        username=unquote(parts.username) if parts.username else None,
        password=unquote(parts.password) if parts.password else None,
        tls=tls,
    )


class MqttLink:
    def __init__(
        self,
        url: str,
        *,
        client_id: str,
        subscriptions: list[str],
        on_message: MessageHandler,
        on_connection: Callable[[bool], None] | None = None,
        keepalive: int = 10,
        max_backoff: float = 5.0,
    ) -> None:
        self.broker = parse_broker_url(url)
        self.subscriptions = subscriptions
        self.on_message = on_message
        self.on_connection = on_connection or (lambda connected: None)
        self.keepalive = keepalive
        self.connects = 0
        self.disconnects = 0
        self._connected = threading.Event()
        # clean_session=False: while only we are away, the broker keeps our QoS 1 inbox.
        self.client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            clean_session=False,
            protocol=paho.MQTTv311,
        )
        if self.broker.username:
            self.client.username_pw_set(self.broker.username, self.broker.password)
        if self.broker.tls:
            self.client.tls_set()
        # paho types these as int but computes with floats; 0.1 s makes a restart cheap.
        self.client.reconnect_delay_set(min_delay=0.1, max_delay=max_backoff)  # type: ignore[arg-type]
        self.client.max_inflight_messages_set(100)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    @property
    def pending(self) -> int:
        """QoS 1 messages not yet acknowledged by the broker."""
        return len(self.client._out_messages)  # paho has no public accessor

    def start(self) -> None:
        # connect_async + loop_start: the loop thread keeps retrying, with backoff, until
        # the broker answers, and again after every disconnect.
        self.client.connect_async(self.broker.host, self.broker.port, self.keepalive)
        self.client.loop_start()

    def wait_connected(self, timeout: float) -> bool:
        return self._connected.wait(timeout)

    def publish(self, topic: str, payload: bytes, qos: int = 1) -> None:
        info = self.client.publish(topic, payload, qos=qos)
        if qos == 0 and info.rc != paho.MQTT_ERR_SUCCESS:
            log.debug("dropped QoS 0 message on %s (not connected)", topic)

    def flush(self, timeout: float) -> bool:
        """Wait until every QoS 1 message is acknowledged; False on timeout."""
        deadline = time.monotonic() + timeout
        while self.pending and time.monotonic() < deadline:
            time.sleep(0.02)
        return not self.pending

    def stop(self, flush_timeout: float = 2.0) -> None:
        if self.connected:
            self.flush(flush_timeout)
        self.client.disconnect()
        self.client.loop_stop()

    # -- paho callbacks (network thread) --------------------------------------------------

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        if reason_code.is_failure:
            log.warning("broker refused the connection: %s", reason_code)
            return
        sock = client.socket()
        if sock is not None:
            try:  # Nagle + delayed ACK cost ~40 ms per request/response (UAVTALK.md)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except OSError:
                pass
        if self.subscriptions:
            client.subscribe([(t, 1) for t in self.subscriptions])
        self.connects += 1
        self._connected.set()
        log.info("connected to %s:%s", self.broker.host, self.broker.port)
        self.on_connection(True)

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        was = self._connected.is_set()
        self._connected.clear()
        if was:
            self.disconnects += 1
            log.warning("disconnected from the broker: %s", reason_code)
            self.on_connection(False)

    def _on_message(self, client, userdata, message) -> None:  # noqa: ANN001
        try:
            self.on_message(message.topic, message.payload)
        except Exception:  # input must never kill the network thread
            log.exception("handler failed for %s", message.topic)

"""Broker Client: one paho-mqtt 2 connection with reconnect, QoS 1 and an outbox.

Nothing published at QoS 1 is lost while the broker is away or restarting: paho keeps
every QoS 1 message until the broker's PUBACK, and resends unacknowledged ones after it
reconnects (in publish order). `pending` counts them. Subscriptions are renewed on every
connect, because a restarted broker without persistence has forgotten the session.

With several broker URLs (the nodes of one RabbitMQ cluster), a lost connection or a
failed connect moves the client to the next node (`attach_failover`); the cluster
mirrors the persistent session's queue, so the QoS 1 inbox follows the drone there.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from urllib.parse import quote, unquote, urlsplit

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


def parse_broker_urls(urls: str | Sequence[str]) -> list[BrokerUrl]:
    """One URL, a comma-separated list of them, or a sequence → every node, in try order."""
    items = urls.split(",") if isinstance(urls, str) else list(urls)
    parsed = [parse_broker_url(u.strip()) for u in items if u.strip()]
    if not parsed:
        raise ValueError("no broker URL given")
    return parsed


class Failover:
    """Moves a paho client to the next broker node after a lost connection or failed connect.

    paho reconnects to `client.host`/`client.port`; changing them between the disconnect
    and paho's next attempt makes that attempt go to another node. The caller's own
    `on_disconnect` / `on_connect_fail` keep running (wrapped, called first).
    """

    def __init__(self, client: paho.Client, brokers: list[BrokerUrl]) -> None:
        self.client = client
        self.brokers = brokers
        self.index = 0
        self.switches = 0
        self.stopping = False
        self._lock = threading.Lock()

    @property
    def current(self) -> BrokerUrl:
        return self.brokers[self.index]

    def advance(self) -> BrokerUrl:
        """Point the client at the next node (a no-op with one node); returns it."""
        with self._lock:
            if len(self.brokers) < 2 or self.stopping:
                return self.current
            self.index = (self.index + 1) % len(self.brokers)
            self.switches += 1
            broker = self.current
            _point_at(self.client, broker)
        log.info("next broker node: %s:%s", broker.host, broker.port)
        return broker


def _point_at(client: paho.Client, broker: BrokerUrl) -> None:
    try:
        client.host = broker.host
        client.port = broker.port
    except RuntimeError:
        # Inside on_disconnect paho still reports the old state for a moment and its
        # setters refuse; the socket is closed already, and reconnect() reads these.
        client._host = broker.host  # noqa: SLF001 - no public way at this point
        client._port = broker.port  # noqa: SLF001
    if broker.username:
        client.username_pw_set(broker.username, broker.password)


def secure(client: paho.Client, tls: bool) -> None:
    """For an mqtts:// broker: TLS with the system's trust store (SSL_CERT_FILE names a
    private CA). A client already set up for TLS is left as it is."""
    if not tls:
        return
    try:
        client.tls_set()
    except ValueError:
        pass  # paho: "SSL/TLS has already been configured"


def attach_failover(client: paho.Client, urls: str | Sequence[str]) -> Failover:
    """Make `client` try the nodes of `urls` in turn; call after setting its callbacks.

    The client starts on the first URL (`connect_async(failover.current.host, ...)`); each
    disconnect that the caller did not ask for, and each failed connect, moves it on.
    """
    failover = Failover(client, parse_broker_urls(urls))
    secure(client, failover.current.tls)
    _point_at(client, failover.current)
    own_disconnect = client.on_disconnect
    own_connect_fail = client.on_connect_fail

    def on_disconnect(c, userdata, flags, reason_code, properties):  # noqa: ANN001, ANN202
        if own_disconnect is not None:
            own_disconnect(c, userdata, flags, reason_code, properties)
        # A disconnect() we asked for reports success: stay where we are.
        if getattr(reason_code, "is_failure", True):
            failover.advance()

    def on_connect_fail(c, userdata):  # noqa: ANN001, ANN202
        if own_connect_fail is not None:
            own_connect_fail(c, userdata)
        failover.advance()

    client.on_disconnect = on_disconnect
    client.on_connect_fail = on_connect_fail
    return failover


def _unparse(broker: BrokerUrl) -> str:
    auth = ""
    if broker.username:
        auth = quote(broker.username, safe="")
        if broker.password is not None:
            auth += ":" + quote(broker.password, safe="")
        auth += "@"
    return f"{'mqtts' if broker.tls else 'mqtt'}://{auth}{broker.host}:{broker.port}"


class MqttLink:
    def __init__(
        self,
        url: str | Sequence[str],
        *,
        client_id: str,
        subscriptions: list[str],
        on_message: MessageHandler,
        on_connection: Callable[[bool], None] | None = None,
        keepalive: int = 10,
        max_backoff: float = 5.0,
    ) -> None:
        self.brokers = parse_broker_urls(url)
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
        # paho types these as int but computes with floats; 0.1 s makes a restart cheap.
        self.client.reconnect_delay_set(min_delay=0.1, max_delay=max_backoff)  # type: ignore[arg-type]
        self.client.max_inflight_messages_set(100)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.failover = attach_failover(self.client, [_unparse(b) for b in self.brokers])

    @property
    def broker(self) -> BrokerUrl:
        """The node this link is connected (or connecting) to."""
        return self.failover.current

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    @property
    def pending(self) -> int:
        """QoS 1 messages not yet acknowledged by the broker."""
        return len(self.client._out_messages)  # paho has no public accessor

    def socket(self) -> socket.socket | None:
        """The connection's socket (None while not connected), for reading the kernel's
        counts of it; never read from or written to outside paho's thread. paho types it
        as its SocketLike: a socket.socket over TCP and TLS, a wrapper over WebSockets."""
        return self.client.socket()  # type: ignore[return-value]

    def start(self) -> None:
        # connect_async + loop_start: the loop thread keeps retrying, with backoff, until
        # the broker answers, and again after every disconnect.
        broker = self.failover.current
        self.client.connect_async(broker.host, broker.port, self.keepalive)
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
        self.failover.stopping = True
        self.client.disconnect()
        self.client.loop_stop()

    # -- paho callbacks (network thread) --------------------------------------------------

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        if reason_code.is_failure:
            log.warning("broker refused the connection: %s", reason_code)
            return
        sock = client.socket()
        if sock is not None:
            try:  # Nagle + delayed ACK cost ~40 ms per request/response (docs/uavtalk.md)
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

"""A competing consumer of one RabbitMQ queue over AMQP (py-amqp), with node failover.

RabbitMQ's MQTT plugin publishes every MQTT message to the `amq.topic` exchange with the
topic as routing key (`A/b/c` → `A.b.c`). Several ground processes sharing one durable
queue bound there split the messages, each taken by one of them: what MQTT shared
subscriptions do on Mosquitto. No Django here (the ingest uses it too).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from urllib.parse import unquote, urlsplit

import amqp

from runtime.retry import Backoff, keep_connected

log = logging.getLogger(__name__)

EXCHANGE = "amq.topic"
QUEUE_PREFIX = "skyhive."
# A queue nobody reads (every consumer of the group down) keeps at most this many
# messages, dropping the oldest: heartbeats and telemetry from hours ago are worthless.
QUEUE_MAX_LENGTH = 1_000_000

OnMessage = Callable[..., object]
# A settled delivery stuck behind one still in hand (another drone's message retried
# through an outage) is acknowledged on its own after this long, so the prefetch window
# does not fill up with finished work.
STRAGGLER_ACK_S = 1.0


def routing_key(topic: str) -> str:
    """The AMQP routing key RabbitMQ's MQTT plugin gives an MQTT topic (or topic filter)."""
    return topic.replace("/", ".").replace("+", "*")


def topic_of(key: str) -> str:
    """The MQTT topic of a routing key (drone ids and channels never contain dots)."""
    return key.replace(".", "/")


class AmqpConsumer:
    """Reads queue `skyhive.<group>` (bound to `*.<channel>.out` on amq.topic) over AMQP.

    One thread: connect to the first reachable node of `urls`, declare and bind the queue,
    consume with a prefetch window and call `on_message(topic, payload)` per message.
    Acknowledgements are batched (`multiple=True`) and sent once the callback returned,
    every `ack_every` messages or when the queue goes quiet, so a crash redelivers only
    what was not yet handed over. A lost node makes it move to the next URL.

    With `manual_ack`, the callback is `on_message(topic, payload, settle)` and a message
    is acknowledged only once `settle()` was called (from any thread): the contiguous
    settled run at once (`multiple=True`), settled ones behind a message still in hand
    one by one after STRAGGLER_ACK_S.
    """

    def __init__(
        self,
        group: str,
        channels: Sequence[str],
        on_message: OnMessage,
        *,
        urls: Sequence[str],
        prefetch: int = 1000,
        ack_every: int | None = None,
        ack_interval: float = 0.05,
        name: str = "",
        heartbeat: int = 10,
        counters: object | None = None,
        manual_ack: bool = False,
    ) -> None:
        if not urls:
            raise ValueError("AMQP_URLS is empty: the RabbitMQ broker needs its AMQP listeners")
        self.queue = QUEUE_PREFIX + group
        self.keys = [routing_key(f"+/{channel}/out") for channel in channels]
        self.on_message = on_message
        self.urls = list(urls)
        self.prefetch = prefetch
        self.ack_every = ack_every or max(1, prefetch // 4)
        self.ack_interval = ack_interval
        self.name = name or f"{group}-{socket.gethostname()}"
        self.heartbeat = heartbeat
        # Anything with incr(name, amount=1): workers.counters.Counters, the ingest's sink.
        self.counters = counters
        self.subscribed = threading.Event()
        self.index = 0
        self.sessions = 0
        self.received = 0
        self.redelivered = 0
        self.callback_errors = 0
        self._stop = threading.Event()
        self._conn: amqp.Connection | None = None
        self._thread: threading.Thread | None = None
        self._unacked_tag: int | None = None
        self._unacked = 0
        self._last_ack = 0.0
        self.manual_ack = manual_ack
        # (session, tag) of settled deliveries, appended from any thread.
        self._settled: deque[tuple[int, int]] = deque()
        # This session's deliveries not acknowledged yet, in tag order: when settled.
        self._outstanding: dict[int, float | None] = {}

    @property
    def url(self) -> str:
        """The node this consumer is connected (or connecting) to."""
        return self.urls[self.index]

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"amqp-{self.queue}", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Acknowledge what was handled, close the connection, wait for the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    # -- the consuming thread ------------------------------------------------------------------

    def _count(self, name: str) -> None:
        if self.counters is not None:
            self.counters.incr(name)  # type: ignore[attr-defined]

    def _run(self) -> None:
        keep_connected(
            self._session,
            stop=self._stop,
            backoff=Backoff(0.1, 2.0),
            errors=(Exception,),  # a consumer outlives any broker fault
            on_lost=self._lost,
            cleanup=self._end_session,
        )

    def _lost(self, exc: BaseException, wait: float) -> None:
        self._count("amqp.disconnects")
        log.warning(
            "%s: AMQP link to %s lost (%s: %s); trying the next node in %.1f s",
            self.name,
            _safe(self.url),
            type(exc).__name__,
            exc,
            wait,
        )
        self.index = (self.index + 1) % len(self.urls)

    def _end_session(self) -> None:
        self.subscribed.clear()
        self._close()

    def _connect(self) -> amqp.Connection:
        parts = urlsplit(self.url)
        vhost = unquote(parts.path[1:]) if len(parts.path) > 1 else "/"
        conn = amqp.Connection(
            host=f"{parts.hostname or '127.0.0.1'}:{parts.port or 5672}",
            userid=unquote(parts.username or "guest"),
            password=unquote(parts.password or "guest"),
            virtual_host=vhost,
            heartbeat=self.heartbeat,
            connect_timeout=5,
            # A node that stops reading must not block an ack or the close for ever.
            write_timeout=5,
            client_properties={"connection_name": self.name},
        )
        conn.connect()
        sock = conn.sock
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return conn

    def _session(self) -> None:
        self._conn = conn = self._connect()
        channel = conn.channel()
        channel.queue_declare(
            self.queue,
            durable=True,
            auto_delete=False,
            arguments={"x-max-length": QUEUE_MAX_LENGTH, "x-overflow": "drop-head"},
        )
        for key in self.keys:
            channel.queue_bind(self.queue, exchange=EXCHANGE, routing_key=key)
        channel.basic_qos(prefetch_size=0, prefetch_count=self.prefetch, a_global=False)
        channel.basic_consume(self.queue, callback=self._deliver, no_ack=False)
        self.sessions += 1
        self._count("amqp.connects")
        self.subscribed.set()
        log.info("%s consuming %s on %s", self.name, self.queue, _safe(self.url))
        self._unacked_tag, self._unacked = None, 0
        self._outstanding.clear()
        self._last_ack = time.monotonic()
        last_beat = time.monotonic()
        while not self._stop.is_set():
            try:
                conn.drain_events(timeout=self.ack_interval)
            except TimeoutError:
                pass
            now = time.monotonic()
            if self.manual_ack:
                self._ack_settled(channel, now)
            elif self._unacked and (
                self._unacked >= self.ack_every or now - self._last_ack >= self.ack_interval
            ):
                self._ack(channel)
            if now - last_beat >= 1.0:
                # Send our heartbeats and notice a silent node.
                conn.heartbeat_tick()
                last_beat = now
        if self.manual_ack:
            self._ack_settled(channel, time.monotonic(), everything=True)
        else:
            self._ack(channel)

    def _deliver(self, message: amqp.Message) -> None:
        info = message.delivery_info
        self.received += 1
        if info.get("redelivered"):
            # Handed to a consumer that went away before acknowledging: maybe seen twice.
            self.redelivered += 1
            self._count("amqp.redelivered")
        body = message.body
        payload = body if isinstance(body, bytes) else bytes(body, "utf-8")
        tag = info["delivery_tag"]
        args: tuple = ()
        if self.manual_ack:
            session = self.sessions
            self._outstanding[tag] = None

            def settle() -> None:
                self._settled.append((session, tag))

            args = (settle,)
        try:
            self.on_message(topic_of(info["routing_key"]), payload, *args)
        except Exception:  # noqa: BLE001 - a bad message must not stop the queue
            self.callback_errors += 1
            self._count("amqp.callback_errors")
            log.exception("%s: callback failed on %s", self.name, info.get("routing_key"))
            if args:
                args[0]()
        self._unacked_tag = tag
        self._unacked += 1

    def _ack_settled(self, channel: amqp.Channel, now: float, everything: bool = False) -> None:
        """Acknowledge what was settled: the settled run from the oldest delivery at once,
        later settled ones when they have waited STRAGGLER_ACK_S behind one in hand."""
        outstanding = self._outstanding
        while self._settled:
            session, tag = self._settled.popleft()
            # A settle from a previous session: RabbitMQ has redelivered that message.
            if session == self.sessions and tag in outstanding:
                outstanding[tag] = now
        run: list[int] = []
        for tag, settled_at in outstanding.items():
            if settled_at is None:
                break
            run.append(tag)
        if run:
            channel.basic_ack(run[-1], multiple=True)
            for tag in run:
                del outstanding[tag]
        if not outstanding:
            return
        stragglers = [
            tag
            for tag, settled_at in outstanding.items()
            if settled_at is not None and (everything or now - settled_at >= STRAGGLER_ACK_S)
        ]
        for tag in stragglers:
            channel.basic_ack(tag)
            del outstanding[tag]

    def _ack(self, channel: amqp.Channel) -> None:
        if self._unacked_tag is not None and self._unacked:
            channel.basic_ack(self._unacked_tag, multiple=True)
        self._unacked_tag, self._unacked = None, 0
        self._last_ack = time.monotonic()

    def _close(self) -> None:
        conn, self._conn = self._conn, None
        if conn is None:
            return
        try:
            conn.close()
        except Exception:  # noqa: BLE001 - the node may be gone; the socket must still go
            try:
                conn.collect()
            except Exception:  # noqa: BLE001
                pass


def _safe(url: str) -> str:
    """A URL without its credentials, for logs."""
    parts = urlsplit(url)
    return f"{parts.hostname}:{parts.port}"

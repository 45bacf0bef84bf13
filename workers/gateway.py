"""The MQTT gateway: the one ground process that talks to the drones' broker.

Inbound, it reads the drones' `/out` topics as one of a group of competing consumers, so
several gateways split the messages without processing one twice: on Mosquitto through
shared subscriptions (`$share/gateway/...`) on its own MQTT connection, on RabbitMQ from
the mirrored AMQP queue `skyhive.gateway` (workers.broker). It parses each message with
`onboard.protocol` and hands it to the domain function named in
`workers.dispatch.DISPATCH`, on a lane of its drone (workers.lanes) off the MQTT network
thread. A QoS 1 message is acknowledged to the broker only once its handler stored it
(or refused it for good), retrying through database and Redis outages meanwhile
(docs/architecture.md, "Store, then acknowledge"). Anything malformed, oversized,
unknown or unauthorised is dropped and counted, never raised. Outbound, it takes from the Redis outbox
(`workers.outbox`) and publishes to `<id>/<channel>/in`, moving to the next broker node when
its node is lost; what it took stays on its own list until the broker acknowledges it,
so a gateway killed in between loses nothing. Being connected anyway, it also writes the
broker's figures for the operations page (workers.broker.figures).
"""

from __future__ import annotations

import json
import logging
import os
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any
from urllib.parse import urlsplit

import kombu.exceptions
import redis
from django.db import close_old_connections, connection
from django.db.utils import DatabaseError, InterfaceError, OperationalError
from django.utils.module_loading import import_string

from onboard import protocol
from onboard.mqtt import parse_broker_url
from runtime.retry import Backoff, retry_call
from workers import broker, outbox
from workers.broker import client as broker_client
from workers.broker.client import Client, Message, Published
from workers.broker.figures import RabbitMQPoller
from workers.broker.mosquitto_sys import SYS_FILTER, SysView
from workers.broker.mqtt_reader import Subscriber
from workers.counters import Counters, is_alive
from workers.lanes import BatchQueue, Lanes

from .dispatch import (
    BATCH_DISPATCH,
    DEFAULT_MAX_PAYLOAD_BYTES,
    DISPATCH,
    MAX_BATCH,
    MAX_PAYLOAD_BYTES,
    MAX_QUEUED,
)

# Handing a message back unacknowledged: the gateway stopped (or gave up) before storing
# it, so the broker delivers it again (to this session on reconnect, or to a peer).
HELD_BACK = "held_back"

# Settles one delivery with the broker (a PUBACK, an AMQP ack): called once the message
# is stored, its task queued, or it is refused for good; never before.
Settle = Callable[[], None]

log = logging.getLogger("gateway")

SHARE_GROUP = "gateway"
# Messages a RabbitMQ node hands one gateway before its acknowledgements: enough to keep
# the handlers busy, few enough that a killed gateway's share is redelivered quickly.
AMQP_PREFETCH = 200
# Heartbeats (QoS 0, a newer one every 5 s) are retried this long through a database
# restart, then dropped and counted; every other message is retried on its lane for as
# long as the outage lasts (see TRANSIENT).
DB_RETRY_S = 20.0
# What a handler writes to, while it is away: the database, Redis (the outbox, command
# replies) and the Celery broker (an alarm's task). A message that meets one of these on
# a lane is retried, unacknowledged, until it passes: an outage of minutes loses nothing.
DB_ERRORS: tuple[type[BaseException], ...] = (OperationalError, InterfaceError)
TRANSIENT: tuple[type[BaseException], ...] = (
    *DB_ERRORS,
    redis.RedisError,
    kombu.exceptions.OperationalError,
)
# The waits between attempts on a lane: short at first (a dropped connection), then every
# few seconds through a restart or an outage.
LANE_BACKOFF = (0.05, 3.0)
# Lanes for everything but heartbeats (batched) and pictures; lanes of their own decode
# pictures, so a drone sending large pictures holds up no other drone's messages.
DRONE_LANES = 4
PICTURE_LANES = 2
APART_CHANNELS = frozenset({"pictures"})
# The batch thread writes at most one batch per this interval: a flood then costs a
# statement per drone every 50 ms rather than per few messages, and a heartbeat (one per
# drone every 5 s) is stored at most this much later.
BATCH_INTERVAL_S = 0.05
# A broker that has not acknowledged a publish in this long has lost us: the message goes
# back to the outbox (paho may still deliver its own copy; drones ignore the repeat).
PUBACK_WAIT_S = 5.0
# How often a gateway looks for outbox messages that a dead gateway had taken. A gateway
# is dead once its heartbeat expires (workers.counters, 10 s).
RECLAIM_EVERY_S = 2.0


def _close_connection() -> None:
    """A lane's own database connection, at its end (a test may share one: left open)."""
    try:
        connection.close()
    except DatabaseError:
        pass


def _counter_names(reason: str | None) -> tuple[str, ...]:
    """What a message's outcome adds to: handled, unhandled.<channel>, or dropped."""
    if reason is None:
        return ("handled",)
    if reason.startswith("unhandled."):
        return (reason,)
    return ("dropped", f"dropped.{reason}")


def subscription(channel: str) -> str:
    return broker.share_filter(SHARE_GROUP, channel)


class Gateway:
    """One paho client (VERSION2 callbacks) plus a thread publishing the outbox; on
    RabbitMQ, an AMQP consumer for the inbound messages as well."""

    def __init__(
        self,
        broker_url: str | Sequence[str] | None = None,
        *,
        dispatch: dict[str, str | None] | None = None,
        batch_dispatch: dict[str, str] | None = None,
        client_id: str | None = None,
        counters: Counters | None = None,
        persistent: bool = False,
        amqp_urls: Sequence[str] | None = None,
        db_retry_s: float = DB_RETRY_S,
    ) -> None:
        # Every node of the cluster, this gateway's first; the outbox is the cluster's,
        # the same for every gateway whichever node it is connected to.
        self.urls = broker.cluster_urls(broker_url)
        self.outbox = outbox.outbox_key(self.urls[0])
        self.counters = counters or Counters("gateway")
        # Named after our heartbeat, so a peer can tell when we are gone.
        self.owner = self.counters.identity
        self.taken = outbox.taken_key(self.outbox, self.owner)
        self.db_retry_s = db_retry_s
        self._load_handlers(dispatch, batch_dispatch)
        # Parsed messages of the batched channels: (topic, channel, drone id, message, settle).
        self._batch = BatchQueue(MAX_QUEUED)
        self._finish = threading.Event()
        # Set by stop(): take nothing new; then, if the lanes do not drain in time, give up
        # retrying (what is left stays unacknowledged with the broker).
        self._closing = threading.Event()
        self._abandon = threading.Event()
        self._generation = 0
        self.lanes = Lanes("gateway-lane", DRONE_LANES, self._work, on_exit=_close_connection)
        self.picture_lanes = Lanes(
            "gateway-pictures", PICTURE_LANES, self._work, on_exit=_close_connection
        )
        self._batch_thread = threading.Thread(
            target=self._run_batches, name="gateway-batches", daemon=True
        )
        self.connected = threading.Event()
        self.stopping = threading.Event()
        stable_id = client_id
        client_id = client_id or f"gateway-{socket.gethostname()}-{os.getpid()}"
        self.consumer = self._amqp_consumer(client_id, amqp_urls)
        # On RabbitMQ the MQTT connection only publishes, so it needs no session of its own.
        persistent = persistent and self.consumer is None
        if persistent and not stable_id:
            raise ValueError("a persistent gateway session needs a stable client_id")
        self.persistent = persistent
        self.client, self.failover = self._mqtt_client(client_id, persistent)
        self.batch_readers = self._batch_readers(client_id)
        self.sys_view, self.rabbitmq_poller = self._broker_watch()
        self._outbox_thread = threading.Thread(
            target=self._publish_outbox, name="gateway-outbox", daemon=True
        )

    def _load_handlers(
        self, dispatch: dict[str, str | None] | None, batch_dispatch: dict[str, str] | None
    ) -> None:
        """The handlers named by dotted path; without a `dispatch`, the platform's tables
        (and no batch handlers unless named, when a `dispatch` is given)."""
        table = DISPATCH if dispatch is None else dispatch
        if batch_dispatch is None:
            batch_dispatch = BATCH_DISPATCH if dispatch is None else {}
        self.handlers: dict[str, Callable[[str, Any], str | None] | None] = {
            channel: import_string(path) if path else None for channel, path in table.items()
        }
        self.batch_handlers: dict[str, Callable[[list[tuple[str, Any]]], list[str | None]]] = {
            channel: import_string(path) for channel, path in batch_dispatch.items()
        }
        self.channels = sorted(set(self.handlers) | set(self.batch_handlers))

    def _amqp_consumer(
        self, client_id: str, amqp_urls: Sequence[str] | None
    ) -> broker.Consumer | None:
        """On RabbitMQ the drones' messages come from a shared AMQP queue; else None."""
        if amqp_urls is None and not broker.uses_amqp():
            return None
        return broker.competing_consumer(
            SHARE_GROUP,
            self.channels,
            self._on_consumed,
            client_id=client_id,
            amqp_urls=list(amqp_urls) if amqp_urls is not None else broker.amqp_urls(),
            prefetch=AMQP_PREFETCH,
            manual_ack=True,
            counters=self.counters,
        )

    def _mqtt_client(self, client_id: str, persistent: bool) -> tuple[Client, broker.Failover]:
        # A persistent session (with a stable client id) makes the broker queue the
        # drones' QoS 1 messages (mission progress, alarms, replies) while this gateway
        # restarts, instead of dropping them. Mosquitto expires abandoned sessions
        # (`persistent_client_expiration`), so a retired instance does not keep its share.
        # Manual acknowledgement: a QoS 1 message is acknowledged once stored (or refused
        # for good), so a gateway killed with it in hand gets it again on reconnect.
        return broker_client.ground_client(
            client_id,
            self.urls,
            clean_session=not persistent,
            manual_ack=True,
            configure=self._configure_client,
        )

    def _configure_client(self, client: Client) -> None:
        client.max_queued_messages_set(10_000)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_connect_fail = self._on_connect_fail
        client.on_message = self._on_message

    def _batch_readers(self, client_id: str) -> dict[str, Subscriber]:
        """On Mosquitto over plain TCP, a fast reader (workers.broker.mqtt_reader) per
        batched channel, on a connection of its own: paho's per-message work would cost
        the heartbeats two thirds of their rate. It settles a QoS 1 delivery only when
        told, as paho does here. Over TLS, and on RabbitMQ, the channel stays on paho or
        the AMQP consumer. The session is clean: heartbeats are QoS 0, never kept for an
        absent subscriber anyway."""
        url = self.urls[0]
        if self.consumer is not None or urlsplit(url).scheme not in ("mqtt", "tcp"):
            return {}
        node = parse_broker_url(url)
        readers = {}
        for channel in self.batch_handlers:
            reader = Subscriber(
                url,
                f"{client_id}-{channel}",
                subscription(channel),
                self._take_batched,
                qos=protocol.QOS[channel],
                manual_ack=True,
            )
            reader.username, reader.password = node.username, node.password  # URL-decoded
            readers[channel] = reader
        return readers

    def _broker_watch(self) -> tuple[SysView | None, RabbitMQPoller | None]:
        """What this gateway writes for the operations page about the broker: on Mosquitto
        its view of `$SYS` and of its link (workers.broker.mosquitto_sys); on RabbitMQ the
        management API's figures, polled on a thread of their own (workers.broker.figures)."""
        if self.consumer is None and not broker.uses_amqp():
            return SysView(outbox.sync_redis(), self.counters.instance), None
        api_urls = broker.rabbitmq_api_urls()
        if self.consumer is not None and api_urls:
            return None, RabbitMQPoller(outbox.sync_redis(), api_urls)
        return None, None

    @property
    def host(self) -> str:
        """The broker node the MQTT connection is on (or trying)."""
        return self.failover.current.host

    @property
    def port(self) -> int:
        return self.failover.current.port

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    # -- lifecycle ------------------------------------------------------------------------

    def start(self) -> None:
        broker_client.connect(self.client, self.failover)
        self.lanes.start()
        self.picture_lanes.start()
        if self.consumer is not None:
            self.consumer.start()
        if self.rabbitmq_poller is not None:
            self.rabbitmq_poller.start()
        self._outbox_thread.start()
        self._batch_thread.start()
        for reader in self.batch_readers.values():
            reader.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Drain: stop taking outbox work and new messages, store what is in hand (given
        `timeout`; the rest stays unacknowledged for redelivery), settle, disconnect."""
        self.stopping.set()
        self._outbox_thread.join(timeout)
        self._closing.set()
        self._drain(timeout)
        self._finish.set()  # nothing new arrives now: the batch thread empties the queue
        self._batch_thread.join(timeout)
        for reader in self.batch_readers.values():
            reader.stop()  # after the batch thread settled what it stored
        if self.consumer is not None:
            self.consumer.stop(timeout)  # sends the acknowledgements settled so far
        if self.rabbitmq_poller is not None:
            self.rabbitmq_poller.stop(timeout)
        broker_client.disconnect(self.client, self.failover)  # after the PUBACKs the lanes queued
        if self.sys_view is not None:
            self.sys_view.reset()
            self.sys_view.flush()
        self.counters.flush()
        close_old_connections()

    def _drain(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        for lanes in (self.lanes, self.picture_lanes):
            if not lanes.stop(max(0.1, deadline - time.monotonic())):
                # A database or Redis still away: what is in hand is not acknowledged.
                self._abandon.set()
                lanes.stop(2.0)

    def wait_connected(self, timeout: float) -> bool:
        """Publishing and receiving: the MQTT connection and, on RabbitMQ, the consumer."""
        deadline = time.monotonic() + timeout
        if not self.connected.wait(timeout):
            return False
        consumers = [*self.batch_readers.values()]
        if self.consumer is not None:
            consumers.append(self.consumer)
        return all(c.subscribed.wait(max(0.0, deadline - time.monotonic())) for c in consumers)

    # -- paho callbacks ---------------------------------------------------------------------

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        if reason_code.is_failure:
            self.counters.incr("connect_refused")
            log.error("broker refused the connection: %s", reason_code)
            self._link_down(f"refused: {reason_code}")
            return
        sock = client.socket()
        if sock is not None:
            # Nagle + delayed ACKs add ~40 ms per command round trip (docs/uavtalk.md).
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self.consumer is None:
            own = [ch for ch in self.channels if ch not in self.batch_readers]
            filters = [(subscription(ch), protocol.QOS[ch]) for ch in own]
            if self.batch_readers and self.persistent:
                # A session kept from before the readers existed still holds theirs.
                client.unsubscribe([subscription(ch) for ch in self.batch_readers])
            if self.sys_view is not None:
                self.sys_view.link_up(self.address)
                filters.append((SYS_FILTER, 0))
            client.subscribe(filters)
        self._generation += 1
        self.counters.incr("connects")
        self.connected.set()
        log.info("connected to %s:%s", self.host, self.port)

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        self.connected.clear()
        if not self.stopping.is_set():
            self.counters.incr("disconnects")
            log.warning("disconnected (%s); reconnecting", reason_code)
            self._link_down(f"disconnected: {reason_code}")

    def _on_connect_fail(self, client, userdata) -> None:  # type: ignore[no-untyped-def]
        self._link_down("cannot connect")

    def _link_down(self, error: str) -> None:
        if self.sys_view is not None:
            self.sys_view.link_down(self.address, error)

    def _on_message(self, client, userdata, message: Message) -> None:  # type: ignore[no-untyped-def]
        if message.topic.startswith("$SYS/"):
            if self.sys_view is not None:
                self.sys_view.remember(message.topic, message.payload)
            return
        settle = None
        if message.qos > 0:
            mid, qos, generation = message.mid, message.qos, self._generation

            def settle() -> None:
                self._ack_mqtt(mid, qos, generation)

        self._on_consumed(message.topic, message.payload, settle)

    def _ack_mqtt(self, mid: int, qos: int, generation: int) -> None:
        # A persistent session gets the unacknowledged message again, under the same
        # packet id, after a reconnect: acknowledging that id is right. A clean session
        # reuses ids for new messages: an old one must not acknowledge them.
        if generation == self._generation or self.persistent:
            self.client.ack(mid, qos)

    def _on_consumed(self, topic_name: str, payload: bytes, settle: Settle | None = None) -> None:
        """From the broker's thread: hand the message to its lane (heartbeats to the
        batch queue) and return at once; it is settled once stored."""
        if self._closing.is_set():
            return  # stopping: left unacknowledged, the broker delivers it again
        parts = topic_name.split("/")
        channel = parts[1] if len(parts) == 3 else ""
        if channel in self.batch_handlers:
            self._take_batched(topic_name, payload, settle)
            return
        try:
            if settle is None and self.lanes.backlog() >= MAX_QUEUED:
                self._count("overload")  # QoS 0 only: QoS 1 is bounded by the broker
                self._count_against_drone(topic_name, "overload")
            else:
                lanes = self.picture_lanes if channel in APART_CHANNELS else self.lanes
                lanes.submit(parts[0], (topic_name, payload, settle))
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a handler
            self.counters.incr("dropped.handler_error")
            log.exception("could not take %s", topic_name)
            if settle is not None:
                settle()  # dropped: it would fail the same way again
        self.counters.maybe_flush()

    def _take_batched(self, topic_name: str, payload: bytes, settle: Settle | None) -> None:
        """A message of a batched channel, from a network thread: parsed here, so that
        parsing overlaps the batch thread's wait on the database, and queued for it; or
        refused (counted, per drone and reason) and settled for good: unparsable, or
        overload when the queue is full (a newer heartbeat follows)."""
        if self._closing.is_set():
            return  # stopping: left unacknowledged, the broker delivers it again
        try:
            parsed = (
                self._parse(topic_name, payload) if len(self._batch) < MAX_QUEUED else "overload"
            )
            if not isinstance(parsed, str):
                channel, drone_id, message = parsed
                if self._batch.put((topic_name, channel, drone_id, message, settle)):
                    return
                parsed = "overload"
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a parser
            log.exception("could not take %s", topic_name)
            parsed = "handler_error"
        self.counters.incr("received")
        self._count(parsed)
        self._count_against_drone(topic_name, parsed)
        if settle is not None:
            settle()

    def _work(self, item: tuple[str, bytes, Settle | None]) -> None:
        """On a lane: handle the message, retrying through outages; settle it unless the
        gateway stopped first."""
        topic_name, payload, settle = item
        try:
            reason = self.handle(topic_name, payload, patient=True)
        except TRANSIENT:
            reason = HELD_BACK
            self.counters.incr("held_back")
            log.warning("stopping with %s not stored: left to the broker", topic_name)
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a handler
            self.counters.incr("dropped.handler_error")
            self._count_against_drone(topic_name, "handler_error")
            log.exception("handler failed on %s", topic_name)
            reason = "handler_error"
        if settle is not None and reason != HELD_BACK:
            settle()
        self.counters.maybe_flush()

    # -- inbound ----------------------------------------------------------------------------

    def handle(self, topic_name: str, payload: bytes, *, patient: bool = False) -> str | None:
        """Process one message; returns None if handled, else why it was dropped/skipped.
        `patient` retries through database and Redis outages until the gateway stops (see
        `with_db_retry`). A batched channel's message is stored alone, as a batch of one."""
        self.counters.incr("received")
        reason = self._handle(topic_name, payload, patient)
        self._count(reason)
        self._count_against_drone(topic_name, reason)
        return reason

    def _count(self, reason: str | None) -> None:
        for name in _counter_names(reason):
            self.counters.incr(name)

    def _count_against_drone(self, topic_name: str, reason: str | None) -> None:
        """A dropped message also counts against the drone of its topic, as
        `<channel>.<reason>`; a topic outside the contract names nobody."""
        if reason is None or reason == "bad_topic" or reason.startswith("unhandled."):
            return
        parts = topic_name.split("/")
        if len(parts) == 3 and parts[1] in protocol.OUT_CHANNELS and protocol.is_drone_id(parts[0]):
            self.counters.refused(parts[0], f"{parts[1]}.{reason}")

    def _handle(self, topic_name: str, payload: bytes, patient: bool) -> str | None:
        parsed = self._parse(topic_name, payload)
        if isinstance(parsed, str):
            return parsed
        channel, drone_id, message = parsed
        if channel in self.batch_handlers:
            batch_handler = self.batch_handlers[channel]
            return self.with_db_retry(batch_handler, [(drone_id, message)], patient=patient)[0]
        handler = self.handlers[channel]
        assert handler is not None
        return self.with_db_retry(handler, drone_id, message, patient=patient)

    def _parse(self, topic_name: str, payload: bytes) -> tuple[str, str, Any] | str:
        """(channel, drone id, parsed message), or why the message is refused."""
        try:
            drone_id, channel, direction = protocol.split_topic(topic_name)
        except protocol.ProtocolError:
            return "bad_topic"
        if direction != "out" or channel not in self.channels:
            return "bad_topic"
        if len(payload) > MAX_PAYLOAD_BYTES.get(channel, DEFAULT_MAX_PAYLOAD_BYTES):
            return "too_large"
        if self.handlers.get(channel) is None and channel not in self.batch_handlers:
            return f"unhandled.{channel}"
        try:
            message = protocol.PARSERS[(channel, "out")](protocol.decode_json(payload))
        except protocol.ProtocolError as exc:
            log.debug("refused %s: %s", topic_name, exc)
            return exc.reason
        return channel, drone_id, message

    def with_db_retry(self, fn: Callable[..., Any], *args: Any, patient: bool = False) -> Any:
        """`fn(*args)`, called again on a fresh connection while the database is
        unreachable (for up to `db_retry_s`); other errors are raised at once. `patient`:
        also while Redis or the Celery broker is, with no time limit until stop() gives
        up. Handlers are transactions that decide by compare-and-set or by the message's
        own key, so a retry (or a redelivery) stores and decides nothing twice."""
        deadline = time.monotonic() + self.db_retry_s
        errors = TRANSIENT if patient else DB_ERRORS

        def attempt() -> Any:
            try:
                return fn(*args)
            except DB_ERRORS:
                # The connection is unusable now: Django opens a fresh one on next use.
                connection.close()
                raise

        def give_up(exc: BaseException, delay: float) -> bool:
            if patient:
                return self._abandon.is_set()
            if self.stopping.is_set() or time.monotonic() + delay > deadline:
                self.counters.incr("db_unavailable")
                return True
            return False

        def on_retry(exc: BaseException, delay: float) -> None:
            database = isinstance(exc, DB_ERRORS)
            self.counters.incr("db_retries" if database else "redis_retries")
            what = "database" if database else "Redis"
            log.warning("%s unavailable (%s); retrying in %.2f s", what, exc, delay)

        return retry_call(
            attempt,
            errors=errors,
            backoff=Backoff(*LANE_BACKOFF) if patient else Backoff(0.05, 1.0),
            give_up=give_up,
            on_retry=on_retry,
            sleep=self._abandon.wait,
        )

    def _run_batches(self) -> None:
        """Store queued messages, as many at once as are waiting; settle them."""
        while not (self._finish.is_set() and not self._batch):
            began = time.monotonic()
            items = self._batch.take(MAX_BATCH, timeout=0.1)
            if items:
                self._run_batch(items)
            self.counters.maybe_flush()
            if len(items) < MAX_BATCH:  # let the next batch gather (not when stopping)
                self._finish.wait(BATCH_INTERVAL_S - (time.monotonic() - began))
        connection.close()

    def _run_batch(self, items: list[tuple[str, str, str, Any, Settle | None]]) -> None:
        """One statement per channel for the parsed messages; every one counted (per
        drone and reason when refused), then settled: stored, or dropped for good."""
        by_channel: dict[str, list[tuple[str, Any]]] = {}
        for _topic, channel, drone_id, message, _settle in items:
            by_channel.setdefault(channel, []).append((drone_id, message))
        outcomes = {
            channel: iter(self._store_batch(channel, batch))
            for channel, batch in by_channel.items()
        }
        counts: Counter[str] = Counter(received=len(items), handled=0)
        for topic_name, channel, _drone_id, _message, _settle in items:
            reason = next(outcomes[channel])
            if reason is None:
                counts["handled"] += 1
            else:
                counts.update(_counter_names(reason))
                self._count_against_drone(topic_name, reason)
        for name, amount in counts.items():
            self.counters.incr(name, amount)
        for *_, settle in items:
            if settle is not None:
                settle()

    def _store_batch(self, channel: str, batch: list[tuple[str, Any]]) -> list[str | None]:
        try:
            return self.with_db_retry(self.batch_handlers[channel], batch)
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a handler
            log.exception("batch handler for %s failed", channel)
            connection.close()
            return ["handler_error"] * len(batch)

    # -- outbound ---------------------------------------------------------------------------

    def _publish_outbox(self) -> None:
        # Alive before taking anything, so no peer mistakes our taken list for a dead one's.
        self.counters.flush()
        next_reclaim = 0.0
        while not self.stopping.is_set():
            if self.sys_view is not None:
                # While disconnected too: the page learns from it that the link is down.
                self.sys_view.flush()
            # Only take work while connected, so another gateway can take it meanwhile.
            if not self.connected.wait(0.5):
                continue
            try:
                if time.monotonic() >= next_reclaim:
                    next_reclaim = time.monotonic() + RECLAIM_EVERY_S
                    self._reclaim()
                raw = outbox.take_outbox(self.outbox, self.taken, timeout=0.25)
                if raw is not None:
                    self.publish_taken(raw)
            except redis.RedisError as exc:
                self.counters.incr("outbox.redis_error")
                log.warning("outbox unavailable: %s", exc)
                self.stopping.wait(1.0)
                continue
            self.counters.maybe_flush()

    def _reclaim(self) -> None:
        """Give back to the outbox what dead gateways had taken and not published."""

        def alive(owner: str) -> bool:
            return owner == self.owner or is_alive(owner, outbox.sync_redis())

        moved = outbox.reclaim_outbox(self.outbox, alive)
        if moved:
            self.counters.incr("outbox.reclaimed", moved)
            log.warning("put back %d outbox message(s) a dead gateway had taken", moved)

    def publish_taken(self, raw: bytes) -> None:
        """Publish one message taken from the outbox; forget it once the broker has it
        (QoS 1: its PUBACK), give it back if the connection went first."""
        try:
            item = json.loads(raw)
        except ValueError:
            self.counters.incr("outbox.malformed")
            outbox.settle_taken(self.taken, raw)
            return
        if self.publish_item(item) is False:
            outbox.give_back(self.outbox, self.taken, raw)
            self.stopping.wait(0.1)  # the connection is going: let it settle
            return
        outbox.settle_taken(self.taken, raw)

    def publish_item(self, item: dict) -> bool | None:
        """True once the broker has it, False if it could not be sent now (connection
        lost: try again), None if it is dropped (expired or refused)."""
        if item.get("expires", 0) < time.time():
            self.counters.incr("outbox.expired")
            return None
        payload = json.dumps(item["payload"], separators=(",", ":"))
        qos = int(item.get("qos", 1))
        info = self.client.publish(item["topic"], payload, qos=qos)
        outcome = broker_client.publish_outcome(info)
        if outcome is Published.NOT_NOW:
            self.counters.incr("outbox.not_sent")
            return False
        if outcome is Published.FAILED:
            self.counters.incr("outbox.publish_failed")
            log.warning("publish to %s failed: %s", item["topic"], broker_client.error_text(info))
            return None
        if qos > 0:
            try:
                info.wait_for_publish(PUBACK_WAIT_S)
            except (RuntimeError, ValueError):
                pass
            if not info.is_published():
                self.counters.incr("outbox.unacknowledged")
                return False
        self.counters.incr("published")
        return True

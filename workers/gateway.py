"""The MQTT gateway: the one ground process that talks to the drones' broker.

Inbound, it subscribes to the drones' `/out` topics through shared subscriptions
(`$share/gateway/...`), so several gateways split the messages without processing one
twice, parses each with `onboard.protocol` and hands it to the domain function named in
`workers.dispatch.DISPATCH`. Anything malformed, oversized, unknown or unauthorised is
dropped and counted, never raised. Outbound, it pops the Redis outbox (`fleet.link`)
and publishes to `<id>/<channel>/in`.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import socket
import threading
import time
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
import redis
from django.db import close_old_connections, connection
from django.db.utils import DatabaseError, InterfaceError
from django.utils.module_loading import import_string

from fleet import link
from onboard import protocol
from workers.counters import Counters

from .dispatch import (
    BATCH_DISPATCH,
    DEFAULT_MAX_PAYLOAD_BYTES,
    DISPATCH,
    MAX_BATCH,
    MAX_PAYLOAD_BYTES,
    MAX_QUEUED,
)

QUEUED = "queued"

log = logging.getLogger("gateway")

SHARE_GROUP = "gateway"


def subscription(channel: str) -> str:
    return f"$share/{SHARE_GROUP}/+/{channel}/out"


class Gateway:
    """One paho client (VERSION2 callbacks) plus a thread publishing the outbox."""

    def __init__(
        self,
        broker_url: str,
        *,
        dispatch: dict[str, str | None] | None = None,
        batch_dispatch: dict[str, str] | None = None,
        client_id: str | None = None,
        counters: Counters | None = None,
        persistent: bool = False,
    ) -> None:
        url = urlsplit(broker_url)
        self.host = url.hostname or "127.0.0.1"
        self.outbox = link.outbox_key(broker_url)
        self.port = url.port or 1883
        self.counters = counters or Counters("gateway")
        table = DISPATCH if dispatch is None else dispatch
        batch_table = (
            (BATCH_DISPATCH if dispatch is None else {})
            if batch_dispatch is None
            else batch_dispatch
        )
        self.handlers: dict[str, Callable[[str, Any], str | None] | None] = {
            channel: import_string(path) if path else None for channel, path in table.items()
        }
        self.batch_handlers: dict[str, Callable[[list[tuple[str, Any]]], list[str | None]]] = {
            channel: import_string(path) for channel, path in batch_table.items()
        }
        self.channels = sorted(set(self.handlers) | set(self.batch_handlers))
        self._queue: queue.Queue[tuple[str, str, Any]] = queue.Queue(maxsize=MAX_QUEUED)
        self._finish = threading.Event()
        self._batch_thread = threading.Thread(
            target=self._run_batches, name="gateway-batches", daemon=True
        )
        self.connected = threading.Event()
        self.stopping = threading.Event()
        # A persistent session (with a stable client id) makes the broker queue the
        # drones' QoS 1 messages (mission progress, alarms, replies) while this gateway
        # restarts, instead of dropping them. Mosquitto expires abandoned sessions
        # (`persistent_client_expiration`), so a retired instance does not keep its share.
        if persistent and not client_id:
            raise ValueError("a persistent gateway session needs a stable client_id")
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=client_id or f"gateway-{socket.gethostname()}-{os.getpid()}",
            clean_session=not persistent,
        )
        if url.username:
            self.client.username_pw_set(url.username, url.password)
        self.client.reconnect_delay_set(min_delay=1, max_delay=30)
        self.client.max_queued_messages_set(10_000)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self._outbox_thread = threading.Thread(
            target=self._publish_outbox, name="gateway-outbox", daemon=True
        )

    # -- lifecycle ------------------------------------------------------------------------

    def start(self) -> None:
        # connect_async + loop_start: paho retries the first connection too, with backoff.
        self.client.connect_async(self.host, self.port, keepalive=30)
        self.client.loop_start()
        self._outbox_thread.start()
        self._batch_thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Drain: stop taking outbox work, finish the message in hand, disconnect."""
        self.stopping.set()
        self._outbox_thread.join(timeout)
        self.client.disconnect()
        self.client.loop_stop()
        self._finish.set()  # nothing new arrives now: the batch thread empties the queue
        self._batch_thread.join(timeout)
        self.counters.flush()
        close_old_connections()

    def wait_connected(self, timeout: float) -> bool:
        return self.connected.wait(timeout)

    # -- paho callbacks ---------------------------------------------------------------------

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        if reason_code.is_failure:
            self.counters.incr("connect_refused")
            log.error("broker refused the connection: %s", reason_code)
            return
        sock = client.socket()
        if sock is not None:
            # Nagle + delayed ACKs add ~40 ms per command round trip (UAVTALK.md).
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.subscribe([(subscription(ch), protocol.QOS[ch]) for ch in self.channels])
        self.counters.incr("connects")
        self.connected.set()
        log.info("connected to %s:%s", self.host, self.port)

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        self.connected.clear()
        if not self.stopping.is_set():
            self.counters.incr("disconnects")
            log.warning("disconnected (%s); reconnecting", reason_code)

    def _on_message(self, client, userdata, message: mqtt.MQTTMessage) -> None:  # type: ignore[no-untyped-def]
        try:
            self.handle(message.topic, message.payload)
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a handler
            self.counters.incr("dropped.handler_error")
            log.exception("handler failed on %s", message.topic)
        self.counters.maybe_flush()

    # -- inbound ----------------------------------------------------------------------------

    def handle(self, topic_name: str, payload: bytes) -> str | None:
        """Process one message; returns None if handled, else why it was dropped/skipped."""
        self.counters.incr("received")
        reason = self._handle(topic_name, payload)
        if reason != QUEUED:
            self._count(reason)
        return reason

    def _count(self, reason: str | None) -> None:
        if reason is None:
            self.counters.incr("handled")
        elif reason.startswith("unhandled."):
            self.counters.incr(reason)
        else:
            self.counters.incr("dropped")
            self.counters.incr(f"dropped.{reason}")

    def _handle(self, topic_name: str, payload: bytes) -> str | None:
        try:
            drone_id, channel, direction = protocol.split_topic(topic_name)
        except protocol.ProtocolError:
            return "bad_topic"
        if direction != "out" or channel not in self.channels:
            return "bad_topic"
        if len(payload) > MAX_PAYLOAD_BYTES.get(channel, DEFAULT_MAX_PAYLOAD_BYTES):
            return "too_large"
        handler = self.handlers.get(channel)
        if handler is None and channel not in self.batch_handlers:
            return f"unhandled.{channel}"
        try:
            message = protocol.PARSERS[(channel, "out")](protocol.decode_json(payload))
        except protocol.ProtocolError as exc:
            log.debug("malformed %s: %s", topic_name, exc)
            return "malformed"
        if channel in self.batch_handlers:
            try:
                self._queue.put_nowait((channel, drone_id, message))
            except queue.Full:
                return "overload"
            return QUEUED
        assert handler is not None
        try:
            return handler(drone_id, message)
        except (InterfaceError, DatabaseError):
            # A dropped database connection: let Django open a fresh one for the next message.
            connection.close()
            raise

    def _run_batches(self) -> None:
        """Hand queued messages to their batch handlers, as many at once as are waiting."""
        while not (self._finish.is_set() and self._queue.empty()):
            try:
                items = [self._queue.get(timeout=0.1)]
            except queue.Empty:
                continue
            while len(items) < MAX_BATCH:
                try:
                    items.append(self._queue.get_nowait())
                except queue.Empty:
                    break
            by_channel: dict[str, list[tuple[str, Any]]] = {}
            for channel, drone_id, message in items:
                by_channel.setdefault(channel, []).append((drone_id, message))
            for channel, batch in by_channel.items():
                self._run_batch(channel, batch)
            self.counters.maybe_flush()
        connection.close()

    def _run_batch(self, channel: str, batch: list[tuple[str, Any]]) -> None:
        try:
            reasons = self.batch_handlers[channel](batch)
        except Exception:  # noqa: BLE001 - the gateway must outlive any bug in a handler
            log.exception("batch handler for %s failed", channel)
            reasons = ["handler_error"] * len(batch)
            # A dropped database connection: let Django open a fresh one next time.
            connection.close()
        for reason in reasons:
            self._count(reason)

    # -- outbound ---------------------------------------------------------------------------

    def _publish_outbox(self) -> None:
        while not self.stopping.is_set():
            # Only take work while connected, so another gateway can take it meanwhile.
            if not self.connected.wait(0.5):
                continue
            try:
                item = link.pop_outbox(self.outbox, timeout=0.25)
            except redis.RedisError as exc:
                self.counters.incr("outbox.redis_error")
                log.warning("outbox unavailable: %s", exc)
                self.stopping.wait(1.0)
                continue
            if item is not None:
                self.publish_item(item)
            self.counters.maybe_flush()

    def publish_item(self, item: dict) -> None:
        if item.get("expires", 0) < time.time():
            self.counters.incr("outbox.expired")
            return
        payload = json.dumps(item["payload"], separators=(",", ":"))
        info = self.client.publish(item["topic"], payload, qos=int(item.get("qos", 1)))
        if info.rc == mqtt.MQTT_ERR_SUCCESS:
            self.counters.incr("published")
        else:
            self.counters.incr("outbox.publish_failed")
            log.warning("publish to %s failed: %s", item["topic"], mqtt.error_string(info.rc))

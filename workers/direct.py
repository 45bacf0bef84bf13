"""A web process's own MQTT connection: commands straight to the drone, replies straight back.

The outbox (workers.outbox) costs a command two extra hops each way: Redis to a gateway,
and the reply from the gateway back through Redis. A web process that may open a broker
connection (settings.COMMAND_DIRECT) keeps one of its own (the ground's credentials,
MQTT_URLS with failover, TLS for mqtts://): it publishes `<id>/control/in` at QoS 1 itself
and receives every `<id>/control/out` on a plain (not shared) subscription, so each web
process sees the replies to what it sent. The rules it keeps:

- At least once, as before: a request counts as sent once the broker acknowledged it
  (PUBACK). Without that acknowledgement within COMMAND_DIRECT_PUBACK_S, or with the
  connection down, the same request goes through the outbox; the drone ignores a
  request id it has seen, so a late copy of the direct publish changes nothing.
- Every reply also reaches Redis: the request is registered as pending there before it is
  published, so the gateways (which also receive `control/out`) hand the reply over as
  they do for any command. The waiter takes its own connection's copy, or the Redis one
  once that connection is lost or the request went through the outbox.
- A reply counts only from the drone that was asked (the topic names it), as in
  `outbox.deliver_reply`.

Replies arrive on paho's network thread; they resolve the waiter's future on its event
loop (`call_soon_threadsafe`).
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass

import redis
from django.conf import settings

from onboard import protocol
from workers import outbox
from workers.broker import client as broker_client
from workers.broker.client import Client, Message, Published

log = logging.getLogger(__name__)

REPLY_FILTER = "+/control/out"
# QoS 1 messages on their way at once: teleoperation and many operators send in parallel.
MAX_INFLIGHT = 200
# What a waiter's future gets when the connection that would have brought its reply went.
LINK_LOST = object()


@dataclass
class _Waiter:
    drone_id: str
    loop: asyncio.AbstractEventLoop
    future: asyncio.Future


class DirectLink:
    """One paho client (VERSION2 callbacks) of one web process; thread-safe."""

    def __init__(self, urls: Sequence[str], client_id: str | None = None) -> None:
        self.urls = list(urls)
        self.pid = os.getpid()
        self.client_id = (
            client_id or f"web-{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:6]}"
        )
        self.ready = threading.Event()
        self._lock = threading.Lock()
        self._waiters: dict[str, _Waiter] = {}
        self._acks: dict[int, tuple[asyncio.AbstractEventLoop, asyncio.Future]] = {}
        self._stopping = False
        self.client, self.failover = broker_client.ground_client(
            self.client_id, self.urls, configure=self._configure
        )

    def _configure(self, client: Client) -> None:
        client.max_inflight_messages_set(MAX_INFLIGHT)
        client.on_connect = self._on_connect
        client.on_subscribe = self._on_subscribe
        client.on_disconnect = self._on_disconnect
        client.on_publish = self._on_publish
        client.on_message = self._on_message

    def start(self) -> DirectLink:
        broker_client.connect(self.client, self.failover)
        return self

    def stop(self) -> None:
        self._stopping = True
        self.ready.clear()
        broker_client.disconnect(self.client, self.failover)
        self._lose_all()

    # -- paho callbacks (network thread) ----------------------------------------------------

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        if reason_code.is_failure:
            log.warning("broker refused the web process's connection: %s", reason_code)
            return
        sock = client.socket()
        if sock is not None:
            # Nagle + delayed ACKs would add ~40 ms to every command's round trip.
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.subscribe(REPLY_FILTER, qos=1)

    def _on_subscribe(self, client, userdata, mid, reason_codes, properties) -> None:  # type: ignore[no-untyped-def]
        # Only once replies can reach us does a command go this way.
        if all(not rc.is_failure for rc in reason_codes):
            self.ready.set()
        else:
            log.warning("broker refused the subscription to %s", REPLY_FILTER)

    def _on_disconnect(self, client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        self.ready.clear()
        if not self._stopping:
            log.warning("web process's broker connection lost (%s); reconnecting", reason_code)
        self._lose_all()

    def _on_publish(self, client, userdata, mid, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        # Called with paho's own lock held: never publish while holding ours.
        with self._lock:
            entry = self._acks.pop(mid, None)
        if entry is None:
            return  # the PUBACK beat its waiter's registration: `publish` sees it anyway
        loop, future = entry
        _resolve_on(loop, future, True)

    def _on_message(self, client, userdata, message: Message) -> None:  # type: ignore[no-untyped-def]
        try:
            drone_id, _channel, _direction = protocol.split_topic(message.topic)
            body = protocol.decode_json(message.payload)
            request_id = body.get("request_id") if isinstance(body, dict) else None
            with self._lock:
                waiter = self._waiters.get(request_id) if isinstance(request_id, str) else None
                if waiter is None or waiter.drone_id != drone_id:
                    return  # not ours, or not from the drone asked: the gateway counts it
            reply = protocol.PARSERS[("control", "out")](body).to_dict()
        except protocol.ProtocolError:
            return  # malformed: the gateway drops and counts it
        with self._lock:
            self._waiters.pop(request_id, None)
        _resolve_on(waiter.loop, waiter.future, reply)

    def _lose_all(self) -> None:
        """The connection went: every waiter turns to Redis, every PUBACK wait ends."""
        with self._lock:
            waiters, self._waiters = self._waiters, {}
            acks, self._acks = self._acks, {}
        for waiter in waiters.values():
            _resolve_on(waiter.loop, waiter.future, LINK_LOST)
        for loop, future in acks.values():
            _resolve_on(loop, future, False)

    # -- the event loop's side --------------------------------------------------------------

    def expect(self, request_id: str, drone_id: str) -> asyncio.Future:
        """A future for the reply to `request_id` from `drone_id` (or LINK_LOST)."""
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        with self._lock:
            self._waiters[request_id] = _Waiter(drone_id, loop, future)
        return future

    def forget(self, request_id: str) -> None:
        with self._lock:
            self._waiters.pop(request_id, None)

    async def publish(self, topic: str, payload: dict, *, qos: int, wait: float) -> bool:
        """True once the broker acknowledged the message (within `wait` seconds)."""
        if not self.ready.is_set():
            return False
        body = json.dumps(payload, separators=(",", ":"))
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        info = self.client.publish(topic, body, qos=qos)
        if broker_client.publish_outcome(info) is not Published.OK:
            return False
        if qos == 0:
            return True
        with self._lock:
            self._acks[info.mid] = (loop, future)
        try:
            if info.is_published():  # acknowledged before the registration above
                return True
            return await asyncio.wait_for(future, wait)
        except TimeoutError:
            return info.is_published()
        finally:
            with self._lock:
                self._acks.pop(info.mid, None)


def _resolve(future: asyncio.Future, value: object) -> None:
    if not future.done():
        future.set_result(value)


def _resolve_on(loop: asyncio.AbstractEventLoop, future: asyncio.Future, value: object) -> None:
    """Resolve `future` on its own loop, from paho's thread. A loop closed meanwhile has
    nobody left waiting; raising here would end paho's network thread."""
    try:
        loop.call_soon_threadsafe(_resolve, future, value)
    except RuntimeError:
        pass


_link: DirectLink | None = None
_link_lock = threading.Lock()


def enabled() -> bool:
    return bool(getattr(settings, "COMMAND_DIRECT", True))


def link() -> DirectLink | None:
    """This process's connection, started on first use (it is ready a moment later; until
    then commands take the outbox). None when direct commands are off. A change of the
    broker settings (tests point them at brokers of their own) opens a new connection."""
    global _link
    if not enabled():
        return None
    urls = list(settings.MQTT_URLS) or [settings.MQTT_URL]
    if settings.MQTT_URL not in urls:
        urls = [settings.MQTT_URL]
    with _link_lock:
        current = _link
        if current is not None and current.urls == urls and current.pid == os.getpid():
            return current
        _link = DirectLink(urls).start()
    if current is not None and current.pid == os.getpid():
        current.stop()
    return _link


def close() -> None:
    """Close this process's connection (a new one opens on next use)."""
    global _link
    with _link_lock:
        current, _link = _link, None
    if current is not None:
        current.stop()


async def _settled(registration: asyncio.Future) -> None:
    try:
        await registration
    except redis.RedisError as exc:
        # Only the copy of the reply through Redis is missing: the direct one still counts.
        log.warning("reply not registered in Redis: %s", exc)


async def arequest(
    drone_id: str, channel: str, message: dict, *, timeout: float | None = None
) -> dict | None:
    """Send a message carrying `request_id` and wait for the drone's answer (None on
    timeout): over this process's connection when it is up, else through the outbox."""
    timeout = settings.COMMAND_TIMEOUT_S if timeout is None else timeout
    current = link()
    if current is None or not current.ready.is_set():
        return await outbox.arequest(drone_id, channel, message, timeout=timeout)
    deadline = time.monotonic() + timeout
    request_id = message["request_id"]
    # Registered in Redis alongside, not before: its command is on the Redis socket before
    # the request leaves (one turn of the loop), so no reply can overtake it, and the
    # request does not wait a Redis round trip.
    expecting = asyncio.ensure_future(outbox.aexpect_reply(drone_id, request_id, timeout))
    await asyncio.sleep(0)
    future = current.expect(request_id, drone_id)
    try:
        wait = float(getattr(settings, "COMMAND_DIRECT_PUBACK_S", 0.5))
        topic = protocol.topic(drone_id, channel, "in")
        if await current.publish(topic, message, qos=protocol.QOS[channel], wait=wait):
            try:
                reply = await asyncio.wait_for(future, max(deadline - time.monotonic(), 0.0))
            except TimeoutError:
                reply = None
        else:
            log.warning(
                "%s not acknowledged by the broker in %g s: sent through the outbox too",
                request_id,
                wait,
            )
            left = max(deadline - time.monotonic(), 0.1)
            await outbox.asend_to_drone(drone_id, channel, message, ttl=left)
            reply = LINK_LOST  # its reply comes through a gateway and Redis
    finally:
        current.forget(request_id)
        await _settled(expecting)
    if reply is LINK_LOST or reply is None:
        # Handed over through Redis meanwhile (by a gateway), or still to come there.
        return await outbox.await_reply(request_id, deadline - time.monotonic())
    # The gateways hand the same reply to Redis too; nobody takes it there, it expires.
    return reply  # type: ignore[return-value]

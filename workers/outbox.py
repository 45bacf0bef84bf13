"""The web ↔ gateway link through Redis.

Commands a web process sends go over its own MQTT connection when it has one
(workers.direct); everything else (missions, envelopes, Celery tasks), and commands while
that connection is down, goes here. To send, a process pushes onto one Redis list (the
outbox) that every gateway takes from (BLMOVE onto a list of its own, so each message is
taken once however many gateways run, and one that a dying gateway had in hand is put
back for the others; drones ignore a request id they have already seen). To wait for a
reply, the sender registers the request id (with the drone it went to) and blocks on a
per-request list; the gateway that receives the drone's answer pushes it there. Any web
process can therefore wait for any reply.
"""

from __future__ import annotations

import asyncio
import json
import time
import weakref
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

import redis
import redis.asyncio as aredis
from django.conf import settings

from onboard import protocol

OUTBOX_PREFIX = "skyhive:gateway:outbox:"
# What each gateway took from an outbox and the broker has not accepted yet.
TAKEN_PREFIX = "skyhive:gateway:taken:"
PENDING_PREFIX = "skyhive:pending:"
REPLY_PREFIX = "skyhive:reply:"
ANSWERED_PREFIX = "skyhive:answered:"
# A reply nobody waits for any more is kept this long, then Redis forgets it.
REPLY_TTL_S = 60

_sync_client: redis.Redis | None = None
_async_clients: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def sync_redis() -> redis.Redis:
    global _sync_client
    if _sync_client is None:
        _sync_client = redis.Redis.from_url(settings.REDIS_URL, socket_timeout=5)
    return _sync_client


def async_redis() -> aredis.Redis:
    """One client per event loop: redis.asyncio connections belong to the loop they ran on."""
    loop = asyncio.get_running_loop()
    client = _async_clients.get(loop)
    if client is None:
        client = aredis.Redis.from_url(settings.REDIS_URL, socket_timeout=None)
        _async_clients[loop] = client
    return client


def outbox_key(broker_url: str | None = None) -> str:
    """The outbox of one broker: gateways on another broker (another deployment or test
    sharing this Redis) never take its messages.

    A cluster has one outbox, named after its first node (MQTT_URLS[0]), whichever node
    the caller names, so every gateway of the cluster pops the list the web pushes to.
    """
    url = urlsplit(broker_url or settings.MQTT_URL)
    address = (url.hostname or "127.0.0.1", url.port or 1883)
    nodes = [urlsplit(u) for u in settings.MQTT_URLS]
    if any((n.hostname or "127.0.0.1", n.port or 1883) == address for n in nodes):
        first = nodes[0]
        address = (first.hostname or "127.0.0.1", first.port or 1883)
    return f"{OUTBOX_PREFIX}{address[0]}:{address[1]}"


def outbox_item(drone_id: str, channel: str, message: dict, *, ttl: float) -> bytes:
    """One outbox entry. `expires` stops a gateway that starts late from sending stale
    commands (a take-off nobody waits for any more)."""
    return json.dumps(
        {
            "topic": protocol.topic(drone_id, channel, "in"),
            "qos": protocol.QOS[channel],
            "payload": message,
            "expires": time.time() + ttl,
        },
        separators=(",", ":"),
    ).encode()


def send_to_drone(drone_id: str, channel: str, message: dict, *, ttl: float | None = None) -> None:
    """Queue `message` for `<drone_id>/<channel>/in`; a gateway publishes it."""
    ttl = settings.COMMAND_TIMEOUT_S if ttl is None else ttl
    sync_redis().rpush(outbox_key(), outbox_item(drone_id, channel, message, ttl=ttl))


async def asend_to_drone(
    drone_id: str, channel: str, message: dict, *, ttl: float | None = None
) -> None:
    ttl = settings.COMMAND_TIMEOUT_S if ttl is None else ttl
    await async_redis().rpush(outbox_key(), outbox_item(drone_id, channel, message, ttl=ttl))


async def arequest(
    drone_id: str, channel: str, message: dict, *, timeout: float | None = None
) -> dict | None:
    """Send a message carrying `request_id` and wait for the drone's answer (None on timeout)."""
    timeout = settings.COMMAND_TIMEOUT_S if timeout is None else timeout
    request_id = message["request_id"]
    pipe = async_redis().pipeline(transaction=False)
    _expect(pipe, drone_id, request_id, timeout)
    pipe.rpush(outbox_key(), outbox_item(drone_id, channel, message, ttl=timeout))
    await pipe.execute()
    return await await_reply(request_id, timeout)


def request_to_drone(drone_id: str, channel: str, message: dict, *, ttl: float) -> None:
    """Send a message carrying `request_id` without waiting: its reply is kept (for
    REPLY_TTL_S) for `reply_to` to read later, as a periodic task does on its next pass."""
    pipe = sync_redis().pipeline(transaction=False)
    _expect(pipe, drone_id, message["request_id"], ttl)
    pipe.rpush(outbox_key(), outbox_item(drone_id, channel, message, ttl=ttl))
    pipe.execute()


def reply_to(request_id: str) -> dict | None:
    """The reply a gateway handed over for a `request_to_drone`, once; None while none came."""
    value = sync_redis().lpop(REPLY_PREFIX + request_id)
    return None if value is None else json.loads(value)


def _expect(client: aredis.Redis, drone_id: str, request_id: str, timeout: float) -> Any:
    return client.set(PENDING_PREFIX + request_id, drone_id, px=int((timeout + 5) * 1000))


async def aexpect_reply(drone_id: str, request_id: str, timeout: float) -> None:
    """Register `request_id` as asked of `drone_id`, so a gateway hands its reply over
    (`deliver_reply`); before the request is sent, or the reply could come first."""
    await _expect(async_redis(), drone_id, request_id, timeout)


async def await_reply(request_id: str, timeout: float) -> dict | None:
    """The reply a gateway handed over for `request_id`, waiting up to `timeout` seconds;
    None (and the request no longer pending) when none came."""
    client = async_redis()
    popped = None
    if timeout > 0:
        popped = await client.blpop([REPLY_PREFIX + request_id], timeout=timeout)
    else:
        value = await client.lpop(REPLY_PREFIX + request_id)
        popped = None if value is None else (None, value)
    if popped is None:
        await client.delete(PENDING_PREFIX + request_id)
        return None
    return json.loads(popped[1])


# Hands a reply over in one step: nothing half done when Redis goes away in between, so
# the gateway may retry it. A copy of a reply already handed over (a QoS 1 redelivery, a
# retry) is recognised by the answered marker and changes nothing.
_DELIVER_REPLY = """
local asked = redis.call('GET', KEYS[1])
if not asked then
  if redis.call('GET', KEYS[3]) == ARGV[1] then return 'again' end
  return 'unexpected_reply'
end
redis.call('DEL', KEYS[1])
if asked ~= ARGV[1] then return 'reply_from_wrong_drone' end
redis.call('RPUSH', KEYS[2], ARGV[2])
redis.call('EXPIRE', KEYS[2], ARGV[3])
redis.call('SET', KEYS[3], ARGV[1], 'EX', ARGV[3])
return 'ok'
"""


def deliver_reply(drone_id: str, request_id: str, reply: dict) -> str | None:
    """Gateway side: hand a drone's answer to whoever waits for it.

    Returns None when delivered (or delivered already: the same reply again), else the
    reason it was dropped: no such request pending, or the answer came from another drone
    than the one asked (a drone must not be able to answer for another).
    """
    keys = [PENDING_PREFIX + request_id, REPLY_PREFIX + request_id, ANSWERED_PREFIX + request_id]
    body = json.dumps(reply, separators=(",", ":"))
    outcome = sync_redis().eval(_DELIVER_REPLY, len(keys), *keys, drone_id, body, REPLY_TTL_S)
    outcome = outcome.decode() if isinstance(outcome, bytes) else outcome
    return None if outcome in ("ok", "again") else outcome


def taken_key(outbox: str, owner: str) -> str:
    """The list of what gateway `owner` took from `outbox` and has not seen the broker
    accept yet."""
    return f"{TAKEN_PREFIX}{outbox[len(OUTBOX_PREFIX) :]}/{owner}"


def take_outbox(outbox: str, taken: str, timeout: float = 1.0) -> bytes | None:
    """Gateway side: move the next message onto the gateway's own `taken` list and return
    it, or None after `timeout` seconds. A gateway that dies with it in hand leaves it
    there for `reclaim_outbox`, instead of losing it as a plain pop would."""
    return sync_redis().blmove(outbox, taken, timeout, "LEFT", "RIGHT")


def settle_taken(taken: str, raw: bytes) -> None:
    """The broker accepted `raw` (or it is dropped for good): forget it."""
    sync_redis().lrem(taken, 1, raw)


def give_back(outbox: str, taken: str, raw: bytes) -> None:
    """Not published after all (the connection went): first in line again, for anyone."""
    pipe = sync_redis().pipeline(transaction=True)
    pipe.lrem(taken, 1, raw)
    pipe.lpush(outbox, raw)
    pipe.execute()


def reclaim_outbox(outbox: str, alive: Callable[[str], bool]) -> int:
    """Put back, first in line, what gateways that are no longer `alive` had taken from
    `outbox`; how many messages. Several gateways may reclaim at once: each message
    moves once."""
    client = sync_redis()
    prefix = taken_key(outbox, "")
    moved = 0
    for key in list(client.scan_iter(match=prefix + "*", count=100)):
        name = key.decode() if isinstance(key, bytes) else key
        if alive(name[len(prefix) :]):
            continue
        while client.lmove(name, outbox, "RIGHT", "LEFT") is not None:
            moved += 1
    return moved

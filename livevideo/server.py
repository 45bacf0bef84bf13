"""The media server's HTTP side: two small ASGI apps over one Relay.

- The drones' app (``drone_app``), the only one reachable from outside the ground:
  ``POST /whip/<drone>`` with an SDP offer (``application/sdp``) and the drone's broker
  credentials (HTTP Basic, RFC 7617) publishes; ``DELETE /whip/<drone>/<session>`` ends
  it ([RFC 9725], WHIP). A drone may publish only under its own id.
- The ground's app (``ground_app``, loopback only): ``POST /whep/<drone>`` with an SDP
  offer and ``Authorization: Bearer <ticket>`` (livevideo.tickets) watches, WHEP-style;
  ``DELETE /whep/<drone>/<session>`` stops; ``GET /streams/<drone>`` describes a stream (``GET /streams``
  every live one),
  ``GET /streams/<drone>/still`` returns its newest frame as JPEG, ``GET /health`` the
  relay's counters and limits.
"""

from __future__ import annotations

import base64
import binascii
import contextlib
import json
import logging
import re
from collections.abc import Awaitable, Callable, Iterator
from typing import Any

import uvicorn

from . import tickets
from .relay import Refused, Relay

log = logging.getLogger(__name__)

Authenticate = Callable[[str, str], Awaitable[int | None]]
Send = Callable[[dict], Awaitable[None]]
Receive = Callable[[], Awaitable[dict]]

DRONE = r"(?P<drone>[A-Za-z0-9_-]{1,64})"
SESSION = r"(?P<session>[A-Za-z0-9_-]{1,64})"


async def respond(
    send: Send,
    status: int,
    body: bytes | dict = b"",
    content_type: str = "application/json",
    headers: list[tuple[bytes, bytes]] | None = None,
) -> None:
    if isinstance(body, dict):
        body = json.dumps(body).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", content_type.encode()),
                (b"content-length", str(len(body)).encode()),
                (b"cache-control", b"no-store"),
                *(headers or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


async def read_body(receive: Receive, limit: int) -> bytes | None:
    """The request body, or None once it passes `limit` bytes (the rest is not read)."""
    chunks: list[bytes] = []
    size = 0
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            return b""
        chunk = message.get("body", b"")
        size += len(chunk)
        if size > limit:
            return None
        chunks.append(chunk)
        if not message.get("more_body"):
            return b"".join(chunks)


def header(scope: dict, name: bytes) -> str:
    for key, value in scope.get("headers", ()):
        if key.lower() == name:
            return value.decode("latin-1")
    return ""


def basic_credentials(value: str) -> tuple[str, str] | None:
    scheme, _, encoded = value.partition(" ")
    if scheme.lower() != "basic":
        return None
    try:
        user, sep, password = base64.b64decode(encoded, validate=True).decode().partition(":")
    except (binascii.Error, UnicodeDecodeError):
        return None
    return (user, password) if sep else None


async def _lifespan(receive: Receive, send: Send) -> None:
    while True:
        message = await receive()
        if message["type"] == "lifespan.startup":
            await send({"type": "lifespan.startup.complete"})
        elif message["type"] == "lifespan.shutdown":
            await send({"type": "lifespan.shutdown.complete"})
            return


async def _read_offer(scope: dict, receive: Receive, send: Send, relay: Relay) -> str | None:
    declared = header(scope, b"content-length")
    if declared.isdigit() and int(declared) > relay.limits.max_offer_bytes:
        body = None
    else:
        body = await read_body(receive, relay.limits.max_offer_bytes)
    if body is None:
        relay.counts["refused_oversize_offer"] += 1
        await respond(send, 413, {"code": "offer_too_large"})
        return None
    if header(scope, b"content-type").split(";")[0].strip() != "application/sdp":
        await respond(send, 415, {"code": "not_sdp", "detail": "send application/sdp"})
        return None
    try:
        return body.decode()
    except UnicodeDecodeError:
        relay.counts["refused_malformed_offer"] += 1
        await respond(send, 400, {"code": "malformed_offer"})
        return None


async def _answered(send: Send, call: Awaitable[tuple[str, str]], location: str) -> None:
    try:
        session, answer = await call
    except Refused as refused:
        await respond(send, refused.status, {"code": refused.code, "detail": str(refused)})
        return
    await respond(
        send,
        201,
        answer.encode(),
        "application/sdp",
        [(b"location", f"{location}/{session}".encode())],
    )


def drone_app(relay: Relay, authenticate: Authenticate) -> Callable[..., Awaitable[None]]:
    publish = re.compile(rf"^/whip/{DRONE}$")
    unpublish = re.compile(rf"^/whip/{DRONE}/{SESSION}$")

    async def app(scope: dict, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await _lifespan(receive, send)
            return
        if scope["type"] != "http":
            return
        path, method = scope["path"], scope["method"]
        match = publish.match(path) or unpublish.match(path)
        if match is None:
            await respond(send, 404, {"code": "not_found"})
            return
        drone_id = match["drone"]
        organisation_id = await _publisher(scope, drone_id, relay, authenticate, send)
        if organisation_id is None:
            return
        if method == "POST" and publish.match(path):
            offer = await _read_offer(scope, receive, send, relay)
            if offer is not None:
                await _answered(send, relay.publish(drone_id, organisation_id, offer), path)
        elif method == "DELETE" and unpublish.match(path):
            ended = await relay.unpublish(drone_id, match["session"])
            await respond(send, 200 if ended else 404, {"ended": ended})
        else:
            await respond(send, 405, {"code": "method_not_allowed"})

    return app


async def _publisher(
    scope: dict, drone_id: str, relay: Relay, authenticate: Authenticate, send: Send
) -> int | None:
    """The publishing drone's organisation, or None after answering 401/403."""
    credentials = basic_credentials(header(scope, b"authorization"))
    if credentials is None:
        relay.counts["refused_no_credentials"] += 1
        await respond(
            send, 401, {"code": "credentials_required"}, headers=[(b"www-authenticate", b"Basic")]
        )
        return None
    user, password = credentials
    organisation_id = await authenticate(user, password)
    if organisation_id is None:
        relay.counts["refused_bad_credentials"] += 1
        await respond(send, 401, {"code": "bad_credentials"})
        return None
    if user != drone_id:
        relay.counts["refused_other_drone"] += 1
        await respond(send, 403, {"code": "other_drone", "detail": "publish your own stream only"})
        return None
    return organisation_id


def ground_app(relay: Relay, ticket_key: bytes) -> Callable[..., Awaitable[None]]:
    watch = re.compile(rf"^/whep/{DRONE}$")
    unwatch = re.compile(rf"^/whep/{DRONE}/{SESSION}$")
    describe = re.compile(rf"^/streams/{DRONE}$")
    still = re.compile(rf"^/streams/{DRONE}/still$")

    async def app(scope: dict, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await _lifespan(receive, send)
            return
        if scope["type"] != "http":
            return
        path, method = scope["path"], scope["method"]
        if path == "/health" and method == "GET":
            await respond(send, 200, relay.health())
        elif path == "/streams" and method == "GET":
            await respond(send, 200, {"streams": relay.describe_all()})
        elif (match := describe.match(path)) and method == "GET":
            await respond(send, 200, relay.describe(match["drone"]))
        elif (match := still.match(path)) and method == "GET":
            await _still(send, relay, match["drone"])
        elif (match := watch.match(path)) and method == "POST":
            organisation_id = await _viewer(scope, relay, ticket_key, match["drone"], send)
            if organisation_id is None:
                return
            offer = await _read_offer(scope, receive, send, relay)
            if offer is not None:
                await _answered(send, relay.watch(match["drone"], organisation_id, offer), path)
        elif (match := unwatch.match(path)) and method == "DELETE":
            if await _viewer(scope, relay, ticket_key, match["drone"], send) is None:
                return
            ended = await relay.unwatch(match["drone"], match["session"])
            await respond(send, 200 if ended else 404, {"ended": ended})
        else:
            await respond(send, 404, {"code": "not_found"})

    return app


async def _viewer(scope: dict, relay: Relay, key: bytes, drone_id: str, send: Send) -> int | None:
    scheme, _, token = header(scope, b"authorization").partition(" ")
    try:
        if scheme.lower() != "bearer":
            raise tickets.TicketError("a viewer ticket is required")
        ticket = tickets.verify(key, token.strip(), drone_id)
    except tickets.TicketError as exc:
        relay.counts["refused_ticket"] += 1
        await respond(send, 403, {"code": "bad_ticket", "detail": str(exc)})
        return None
    return ticket.organisation_id


async def _still(send: Send, relay: Relay, drone_id: str) -> None:
    still: Any = relay.still(drone_id)
    if still is None:
        await respond(send, 404, {"code": "not_live"})
        return
    jpeg, captured = still
    headers = [(b"x-capture-time-ms", str(captured).encode())] if captured is not None else []
    await respond(send, 200, jpeg, "image/jpeg", headers)


class SharedLoopServer(uvicorn.Server):
    """Uvicorn for one of several servers in one event loop: their owner handles signals."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield

"""Viewer tickets: the portal's signed word that a viewer may watch one drone's stream.

The portal issues a ticket to a member of the drone's organisation; the media server
checks it on its own (the same key, from the project's secrets) before it sends a single
frame, so a request that bypasses the portal is refused there too. A ticket names the
drone, the viewer's organisation and an expiry; it is HMAC-SHA256 (RFC 2104) over
those, encoded base64url (RFC 4648 section 5) without padding.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import time
from dataclasses import dataclass


class TicketError(ValueError):
    """The ticket is missing, malformed, forged, expired or for another drone."""


@dataclass(frozen=True)
class Ticket:
    drone_id: str
    organisation_id: int
    expires: int  # Unix seconds


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


def _signature(key: bytes, payload: bytes) -> bytes:
    return hmac.new(key, b"skyhive-live-video-ticket\0" + payload, hashlib.sha256).digest()


def mint(
    key: bytes, drone_id: str, organisation_id: int, ttl_s: float, now: float | None = None
) -> str:
    if not key:
        raise ValueError("a ticket key is required")
    expires = int((time.time() if now is None else now) + ttl_s)
    payload = f"{drone_id}|{organisation_id}|{expires}".encode()
    return f"{_b64(payload)}.{_b64(_signature(key, payload))}"


def verify(key: bytes, ticket: str, drone_id: str, now: float | None = None) -> Ticket:
    """The ticket's content when it is genuine, unexpired and for `drone_id`."""
    try:
        encoded, signature = ticket.split(".")
        payload = _unb64(encoded)
        given = _unb64(signature)
    except (ValueError, TypeError) as exc:
        raise TicketError("malformed ticket") from exc
    if not key or not hmac.compare_digest(_signature(key, payload), given):
        raise TicketError("ticket signature does not match")
    try:
        named, organisation, expires = payload.decode().split("|")
        parsed = Ticket(named, int(organisation), int(expires))
    except (ValueError, UnicodeDecodeError) as exc:
        raise TicketError("malformed ticket") from exc
    if parsed.expires < (time.time() if now is None else now):
        raise TicketError("ticket expired")
    if parsed.drone_id != drone_id:
        raise TicketError("ticket is for another drone")
    return parsed

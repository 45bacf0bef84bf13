"""The portal's calls to the media server's loopback side (settings.LIVE_VIDEO_URL)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from dataclasses import dataclass

from django.conf import settings

from . import access, tickets

TIMEOUT_S = 10.0


class MediaServerUnavailable(RuntimeError):
    """The media server did not answer."""


@dataclass(frozen=True)
class Reply:
    status: int
    body: bytes
    content_type: str
    headers: dict[str, str]


def _call(
    method: str, path: str, body: bytes | None = None, headers: dict[str, str] | None = None
) -> Reply:
    request = urllib.request.Request(
        settings.LIVE_VIDEO_URL.rstrip("/") + path, data=body, method=method, headers=headers or {}
    )
    try:
        with urllib.request.urlopen(request, timeout=TIMEOUT_S) as response:
            return Reply(response.status, response.read(), response.headers.get_content_type(),
                         dict(response.headers))  # fmt: skip
    except urllib.error.HTTPError as exc:
        return Reply(exc.code, exc.read(), exc.headers.get_content_type(), dict(exc.headers))
    except (OSError, ValueError) as exc:
        raise MediaServerUnavailable(str(exc)) from exc


def describe(drone_id: str) -> dict:
    reply = _call("GET", f"/streams/{drone_id}")
    if reply.status != 200:
        raise MediaServerUnavailable(f"media server answered {reply.status}")
    return json.loads(reply.body)


def live_streams() -> dict[str, dict]:
    """Every live stream by drone id."""
    reply = _call("GET", "/streams")
    if reply.status != 200:
        raise MediaServerUnavailable(f"media server answered {reply.status}")
    return json.loads(reply.body)["streams"]


def _ticket(drone_id: str, organisation_id: int) -> dict[str, str]:
    ticket = tickets.mint(
        access.ticket_key(), drone_id, organisation_id, settings.LIVE_VIDEO_TICKET_TTL_S
    )
    return {"Authorization": f"Bearer {ticket}"}


def watch(drone_id: str, organisation_id: int, offer: bytes) -> Reply:
    headers = {"Content-Type": "application/sdp", **_ticket(drone_id, organisation_id)}
    return _call("POST", f"/whep/{drone_id}", offer, headers)


def unwatch(drone_id: str, organisation_id: int, session: str) -> Reply:
    return _call("DELETE", f"/whep/{drone_id}/{session}", None, _ticket(drone_id, organisation_id))


def still(drone_id: str) -> tuple[bytes, int | None] | None:
    """The stream's newest frame (JPEG) and its capture time (ms), None when not live."""
    reply = _call("GET", f"/streams/{drone_id}/still")
    if reply.status == 404:
        return None
    if reply.status != 200:
        raise MediaServerUnavailable(f"media server answered {reply.status}")
    captured = reply.headers.get("X-Capture-Time-Ms") or reply.headers.get("x-capture-time-ms")
    return reply.body, int(captured) if captured else None

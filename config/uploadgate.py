"""Who may send an upload, decided from its headers before a byte of its body is read.

Django's ASGI handler receives the whole body (spooled to disk) before any middleware or
view runs, so a view's checks come after the upload has cost its disk and bandwidth. For
the upload addresses (`GATES`) the request is authenticated here first, from its headers
alone, by the project's own rules: the API's authentication classes (REST_FRAMEWORK's
DEFAULT_AUTHENTICATION_CLASSES with their CSRF, read-only-token and second-factor
refusals) and the operator role for the log upload; the session and the admin site's own
permission for the map-tile, terrain and zone file uploads. A refusal is answered 401/403 with
`Connection: close` and the body is never received; a user who already has
UPLOAD_MAX_CONCURRENT uploads under way at that address gets 429. The other addresses
that take more than REQUEST_BODY_MAX_BYTES (missions, plans, envelopes) need a signed-in
sender (`signed_in_sender`). The view checks everything again after the body
(organisation, role, file): this gate only keeps strangers from costing anything.
`config/bodylimits.py` runs it for every HTTP request.
"""

from __future__ import annotations

import io
import json
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from asgiref.sync import sync_to_async
from django.conf import settings
from django.contrib.auth.middleware import AuthenticationMiddleware
from django.contrib.sessions.middleware import SessionMiddleware
from django.core.cache import cache
from django.core.exceptions import SuspiciousOperation
from django.core.handlers.asgi import ASGIRequest
from django.db import close_old_connections
from django.http import HttpRequest
from rest_framework.exceptions import APIException
from rest_framework.permissions import SAFE_METHODS
from rest_framework.request import Request
from rest_framework.settings import api_settings

from logs.asgi import UPLOAD_PATH as LOG_UPLOAD_PATH
from terrain.admin import TERRAIN_UPLOAD_PATH
from tiles.admin import TILE_UPLOAD_PATH
from zones.admin import ZONES_UPLOAD_PATH

Receive = Callable[[], Awaitable[dict]]
Send = Callable[[dict], Awaitable[None]]
ASGIApp = Callable[[dict, Receive, Send], Awaitable[None]]

# A slot outlives a server that died mid-upload by this long; a live upload renews it.
SLOT_TTL_S = 120
RENEW_EVERY_S = 30
# Headers that describe the body: left out of the probe so nothing tries to parse one.
BODY_HEADERS = (b"content-length", b"content-type", b"transfer-encoding")


@dataclass(frozen=True)
class Refusal:
    status: int
    code: str
    message: str


def _signed_out() -> Refusal:
    return Refusal(401, "not_authenticated", "Sign in, or send an API token, to upload.")


def log_uploader(request: HttpRequest) -> Refusal | Any:
    """The user who may upload a flight log: authenticated by the API's own classes, an
    operator in an organisation the credential reaches (a token's own, else any)."""
    from fleet.models import Membership, Role

    authenticators = [cls() for cls in api_settings.DEFAULT_AUTHENTICATION_CLASSES]
    api = Request(request, authenticators=authenticators)
    try:
        user, auth = api.user, api.auth
    except APIException as exc:
        return _refusal_of(exc)
    if not user.is_authenticated:
        return _signed_out()
    memberships = Membership.objects.for_user(user)
    if getattr(auth, "organisation_id", None):
        memberships = memberships.filter(organisation_id=auth.organisation_id)
    if not any(m.allows(Role.OPERATOR) for m in memberships):
        return Refusal(403, "permission_denied", "Uploading logs needs the operator role.")
    return user


def _admin_uploader(request: HttpRequest, permission: str, message: str) -> Refusal | Any:
    """The user, signed in to the admin site with `permission`; else why not."""
    from django.contrib import admin

    user = request.user
    if not user.is_authenticated:
        return _signed_out()
    if not (admin.site.has_permission(request) and user.has_perm(permission)):
        return Refusal(403, "permission_denied", message)
    return user


def tile_uploader(request: HttpRequest) -> Refusal | Any:
    """The user who may import a tile set: signed in to the admin site, with its add right."""
    return _admin_uploader(request, "tiles.add_tileset", "Importing map tiles needs the admin's right to add tile sets.")  # fmt: skip


def terrain_uploader(request: HttpRequest) -> Refusal | Any:
    """The user who may import terrain: signed in to the admin site, with its add right."""
    return _admin_uploader(request, "terrain.add_terraintile", "Importing terrain needs the admin's right to add terrain tiles.")  # fmt: skip


def zones_uploader(request: HttpRequest) -> Refusal | Any:
    """The user who may import a zone file: signed in to the admin site, with its add right."""
    return _admin_uploader(request, "zones.add_zone", "Importing zones needs the admin's right to add zones.")  # fmt: skip


GATES: dict[str, Callable[[HttpRequest], Refusal | Any]] = {
    LOG_UPLOAD_PATH: log_uploader,
    TILE_UPLOAD_PATH: tile_uploader,
    TERRAIN_UPLOAD_PATH: terrain_uploader,
    ZONES_UPLOAD_PATH: zones_uploader,
}


def signed_in_sender(request: HttpRequest) -> Refusal | Any:
    """Anyone signed in (the API's own authentication on /api/, the session elsewhere):
    for the addresses that take more than the default body (missions, plans, envelopes),
    whose views judge the rest."""
    if request.path.startswith("/api/"):
        authenticators = [cls() for cls in api_settings.DEFAULT_AUTHENTICATION_CLASSES]
        api = Request(request, authenticators=authenticators)
        try:
            user = api.user
        except APIException as exc:
            return _refusal_of(exc)
    else:
        user = request.user
    return user if user.is_authenticated else _signed_out()


def _refusal_of(exc: APIException) -> Refusal:
    codes = exc.get_codes()
    return Refusal(exc.status_code, codes if isinstance(codes, str) else "refused", str(exc.detail))  # fmt: skip


def gate_for(scope: dict, limit: int | None) -> Callable[[HttpRequest], Refusal | Any] | None:
    """Who decides on this request before its body: an upload's gate, `signed_in_sender`
    for a body that may exceed REQUEST_BODY_MAX_BYTES, else nobody."""
    if scope["type"] != "http" or scope.get("method") in SAFE_METHODS:
        return None
    if scope.get("path", "") in GATES:
        return GATES[scope["path"]]
    if limit is not None and limit > int(settings.REQUEST_BODY_MAX_BYTES):
        return signed_in_sender
    return None


def probe(scope: dict) -> HttpRequest:
    """The request as Django would see it, with its cookies and session but no body."""
    headers = [(k, v) for k, v in scope.get("headers", []) if k.lower() not in BODY_HEADERS]
    request = ASGIRequest({**scope, "headers": headers}, io.BytesIO(b""))
    SessionMiddleware(_no_response).process_request(request)
    AuthenticationMiddleware(_no_response).process_request(request)
    return request


def _no_response(request: HttpRequest) -> None:
    return None


def slot_key(path: str, user_id: int, index: int) -> str:
    """The cache key of one of a user's upload slots at `path`."""
    return f"upload-slot:{path}:{user_id}:{index}"


def take_slot(path: str, user_id: int) -> str | None:
    """One of the user's UPLOAD_MAX_CONCURRENT slots at `path` (a cache key), or None."""
    for index in range(int(settings.UPLOAD_MAX_CONCURRENT)):
        key = slot_key(path, user_id, index)
        if cache.add(key, 1, SLOT_TTL_S):  # SET NX: two requests cannot take one slot
            return key
    return None


def admit(scope: dict, decide: Callable[[HttpRequest], Refusal | Any]) -> Refusal | str:
    """A refusal, or the slot the upload holds while it runs."""
    close_old_connections()
    try:
        verdict = decide(probe(scope))
    except SuspiciousOperation as exc:  # a host not allowed, a malformed cookie
        verdict = Refusal(400, "bad_request", str(exc) or "Bad request.")
    finally:
        close_old_connections()
    if isinstance(verdict, Refusal):
        return verdict
    if scope["path"] not in GATES or scope["method"] != "POST":
        return ""  # not an upload: no slot to hold
    slot = take_slot(scope["path"], verdict.pk)
    if slot is None:
        limit = int(settings.UPLOAD_MAX_CONCURRENT)
        return Refusal(429, "too_many_uploads", f"You already have {limit} uploads under way here; wait for one to finish.")  # fmt: skip
    return slot


async def guard(scope: dict, receive: Receive, send: Send, app: ASGIApp, decide: Any) -> None:
    """Run `app` for an upload `decide` admits; answer the refusal otherwise."""
    # A thread of the pool, not Django's one shared thread: uploads are not queued
    # behind each other's checks (each opens and closes its own connection).
    verdict = await sync_to_async(admit, thread_sensitive=False)(scope, decide)
    if isinstance(verdict, Refusal):
        await refuse(send, verdict)
        return
    renewed = time.monotonic()

    async def renewing_receive() -> dict:
        nonlocal renewed
        if time.monotonic() - renewed > RENEW_EVERY_S:
            renewed = time.monotonic()
            if verdict:
                await cache.atouch(verdict, SLOT_TTL_S)
        return await receive()

    async def releasing_send(message: dict) -> None:
        # Free the slot before the answer's last byte: a client that starts its next
        # upload on this answer must find it free.
        if verdict and message["type"] == "http.response.body" and not message.get("more_body"):
            await cache.adelete(verdict)
        await send(message)

    try:
        await app(scope, renewing_receive, releasing_send)
    finally:
        if verdict:
            await cache.adelete(verdict)


async def refuse(send: Send, refusal: Refusal) -> None:
    body = json.dumps({"error": refusal.message, "code": refusal.code, "fields": {}}).encode()
    headers = [(b"content-type", b"application/json"), (b"connection", b"close"),
               (b"content-length", str(len(body)).encode())]  # fmt: skip
    if refusal.status == 401:
        headers.append((b"www-authenticate", b'Token realm="api"'))
    await send({"type": "http.response.start", "status": refusal.status, "headers": headers})
    await send({"type": "http.response.body", "body": body})

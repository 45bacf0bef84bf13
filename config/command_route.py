"""`POST /api/v1/drones/{id}/commands/` at MQTT speed: a command that passes every check,
answered without Django's request cycle.

Django's handler, middleware and DRF cost a command about 4 ms on this path before the
drone is even asked. This ASGI layer takes only requests it can answer exactly as the API
view would, and only once every check passed:

- a personal token (`Authorization: Token sky_…`), no cookie, no query string, a JSON
  body of the announced Content-Length, and an answer in JSON (no `Accept` asking for
  anything else);
- the host allowed and no redirect due (Django's own SecurityMiddleware and
  CommonMiddleware hooks decide);
- the token usable and its user an operator of the drone's organisation (one query each,
  on the event loop: accounts.tokens.afind_usable, fleet.commands.afind_drone);
- the body a control command the API knows, its parameters valid, the drone online and
  the move inside the envelope (fleet.commands.checked, the view's own checks).

Anything else, including every refusal and any database error, goes to Django untouched
(the body handed on as it came), which answers, and logs a refusal, as it always has. A
request taken here is sent, logged and answered by the view's own code
(fleet.commands.execute, fleet.api.command_reply); the answer carries the headers Django's
middleware would add. COMMAND_ROUTE=false sends every request to Django.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Awaitable, Callable
from functools import partial
from io import BytesIO
from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings
from django.core.exceptions import DisallowedHost, PermissionDenied
from django.core.handlers.asgi import ASGIRequest
from django.http import HttpResponse
from django.middleware.clickjacking import XFrameOptionsMiddleware
from django.middleware.common import CommonMiddleware
from django.middleware.security import SecurityMiddleware
from rest_framework.exceptions import ParseError
from rest_framework.parsers import JSONParser
from rest_framework.renderers import JSONRenderer

from accounts import audit, tokens
from config.api import exception_handler
from fleet import api, commands
from fleet.async_views import run_after_answer
from fleet.models import Drone
from onboard import protocol

log = logging.getLogger(__name__)

ASGIApp = Callable[[dict, Callable[[], Awaitable[dict]], Callable[[dict], Awaitable[None]]], Any]

PATH = re.compile(r"^/api/v1/drones/([A-Za-z0-9_-]{1,64})/commands/$")
# A command's body is a few hundred bytes; anything much larger is Django's to judge.
BODY_MAX = 64 * 1024
JSON_ANSWERS = (b"", b"*/*", b"application/json")
FIELDS = {"command", "params", "confirm_beyond_defaults"}  # the view's serializer's


def _unused(request: Any) -> None:  # the middleware below is only asked its hooks
    return None


_security = SecurityMiddleware(_unused)
_common = CommonMiddleware(_unused)
_xframe = XFrameOptionsMiddleware(_unused)


class CommandRoute:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        drone_id = _candidate(scope)
        if drone_id is None:
            return await self.app(scope, receive, send)
        messages, body = await _body(receive)
        taken = None if body is None else await _checked(scope, body, drone_id)
        if taken is None:
            return await self.app(scope, _replaying(messages, receive), send)
        await _serve(*taken, send)


def _candidate(scope: dict) -> str | None:
    """The drone id, when the request has the shape this route takes."""
    if scope["type"] != "http" or scope["method"] != "POST" or scope.get("root_path"):
        return None
    if scope.get("query_string") or not getattr(settings, "COMMAND_ROUTE", True):
        return None
    match = PATH.match(scope["path"])
    if match is None:
        return None
    headers = dict(scope["headers"])
    if len(headers) != len(scope["headers"]):
        return None  # a repeated header: Django joins them, so its reading decides
    kind = headers.get(b"content-type", b"").strip().lower()
    if b"cookie" in headers or kind != b"application/json":
        return None
    if headers.get(b"accept", b"").strip().lower() not in JSON_ANSWERS:
        return None
    if b"content-length" not in headers:
        return None  # DRF reads no body without one (and `_checked` compares it)
    return match.group(1)


async def _body(receive: Callable) -> tuple[list[dict], bytes | None]:
    """The messages read (to hand on) and the body; None past BODY_MAX or on disconnect."""
    messages: list[dict] = []
    chunks: list[bytes] = []
    size = 0
    while True:
        message = await receive()
        messages.append(message)
        if message["type"] != "http.request":
            return messages, None
        chunks.append(message.get("body", b""))
        size += len(chunks[-1])
        if size > BODY_MAX:
            return messages, None
        if not message.get("more_body"):
            return messages, b"".join(chunks)


def _replaying(messages: list[dict], receive: Callable) -> Callable[[], Awaitable[dict]]:
    pending = list(messages)

    async def replay() -> dict:
        return pending.pop(0) if pending else await receive()

    return replay


def _order(body: bytes) -> tuple[str, dict, bool] | None:
    """(command, params, confirmed) as the API's serializer would take them, or None."""
    try:
        order = JSONParser().parse(BytesIO(body))
    except ParseError:
        return None
    if not isinstance(order, dict) or not set(order) <= FIELDS:
        return None
    command, params = order.get("command"), order.get("params", {})
    confirmed = order.get("confirm_beyond_defaults", False)
    if command not in protocol.CONTROL_COMMANDS or not isinstance(params, dict):
        return None
    if not isinstance(confirmed, bool):
        return None
    return command, params, confirmed


def _request(scope: dict, body: bytes) -> ASGIRequest | None:
    """Django's view of the request, if Django would hand it to a view at all."""
    request = ASGIRequest(scope, BytesIO(body))
    try:
        if _security.process_request(request) or _common.process_request(request):
            return None  # a redirect
    except (DisallowedHost, PermissionDenied):
        return None
    return request


async def _checked(scope: dict, body: bytes, drone_id: str) -> tuple | None:
    """(request, token, prepared) for a command that passes every check, else None."""
    order = _order(body)
    request = _request(scope, body) if order is not None else None
    if order is None or request is None or request.META["CONTENT_LENGTH"] != str(len(body)):
        return None
    key = request.headers.get("Authorization", "").split()
    if len(key) != 2 or key[0].lower() != "token":
        return None
    try:
        token = await tokens.afind_usable(key[1])
        if token is None or token.read_only:
            return None
        drone = await commands.afind_drone(token.user, drone_id)
        if drone is None:
            return None
        prepared = commands.checked(token.user, drone, *order)
    except commands.CommandRefused:
        return None
    except Exception:  # noqa: BLE001 - Django serves it instead, and says what went wrong
        log.warning("command route declined a request on an error", exc_info=True)
        return None
    request.user = token.user
    return request, token, prepared


async def _serve(
    request: ASGIRequest, token: Any, prepared: commands.Prepared, send: Callable
) -> None:
    answered: list[Callable[[], None]] = []
    with audit.serving(request):  # the log entry's audit record names the caller's address
        outcome = await commands.execute(prepared, after_answer=answered)
    await _send(_response(request, prepared.drone, outcome), send)
    answered.append(partial(tokens.touch, token))
    await database_sync_to_async(run_after_answer)(answered)


def _response(request: ASGIRequest, drone: Drone, outcome: commands.Outcome) -> HttpResponse:
    """The view's answer, with the headers the view and Django's middleware give it."""
    try:
        answer = api.command_reply(drone.drone_id, outcome)
    except api.NoReply as exc:
        answer = exception_handler(exc, {})
    response = HttpResponse(
        JSONRenderer().render(answer.data),
        status=answer.status_code,
        content_type="application/json",
    )
    for header, value in api.DroneCommandView().default_response_headers.items():
        response[header] = value
    for middleware in (_xframe, _common, _security):  # Django's order, innermost first
        response = middleware.process_response(request, response)
    return response


async def _send(response: HttpResponse, send: Callable) -> None:
    headers = [(k.encode("latin-1"), v.encode("latin-1")) for k, v in response.items()]
    await send({"type": "http.response.start", "status": response.status_code, "headers": headers})
    await send({"type": "http.response.body", "body": response.content})

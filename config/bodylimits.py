"""The largest request body each address accepts: HTTP 413 beyond it, before any view runs.

Limits are a table in the settings (REQUEST_BODY_LIMITS: path pattern → bytes, the first
match wins; REQUEST_BODY_MAX_BYTES for every other address). DRF reads JSON bodies from
the request stream, past Django's DATA_UPLOAD_MAX_MEMORY_SIZE, so without this a 1 GB
envelope or mission would be parsed in memory. Two layers use the same table:

- `BodyLimitMiddleware` (Django): refuses by the announced Content-Length, and turns
  Django's own "too big / too many fields" refusals into 413 instead of 400;
- `BodyLimitASGI` (config/asgi.py): also cuts off a body that grows past the limit
  without announcing its length, before Django spools it to disk, and lets an upload in
  only once its sender is known to be allowed to send it (config/uploadgate.py).

A pattern whose limit is None is left to the endpoint for POSTs (the log upload streams
to disk with its own limit, logs/asgi.py); other methods there get the default.
"""

from __future__ import annotations

import json
import re
from collections.abc import Awaitable, Callable
from functools import lru_cache

from django.conf import settings
from django.core.exceptions import RequestDataTooBig, TooManyFieldsSent
from django.http import HttpRequest, HttpResponse, JsonResponse
from django.utils.deprecation import MiddlewareMixin

from config import uploadgate
from config.middleware import EventLoopHooks

ASGIApp = Callable[
    [dict, Callable[[], Awaitable[dict]], Callable[[dict], Awaitable[None]]], Awaitable[None]
]


@lru_cache(maxsize=8)
def _compiled(table: tuple[tuple[str, int | None], ...]) -> list[tuple[re.Pattern, int | None]]:
    return [(re.compile(pattern), limit) for pattern, limit in table]


def limit_for(path: str) -> int | None:
    """The body limit of `path` in bytes; None when the endpoint enforces its own."""
    table = tuple((pattern, limit) for pattern, limit in settings.REQUEST_BODY_LIMITS)
    for pattern, limit in _compiled(table):
        if pattern.search(path):
            return limit
    return int(settings.REQUEST_BODY_MAX_BYTES)


def human(size: int) -> str:
    for unit, factor in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if size >= factor:
            return f"{size / factor:g} {unit}"
    return f"{size} bytes"


def refusal(limit: int) -> dict:
    """The API's error shape (config/api.py) for a body over `limit`."""
    return {
        "error": f"The request body is larger than {human(limit)}, the limit for this address; "
        "nothing was stored.",
        "code": "too_large",
        "fields": {},
    }


def _content_length(value: str | bytes | None) -> int | None:
    try:
        return int(value) if value not in (None, "", b"") else None
    except ValueError:
        return None


class BodyLimitMiddleware(EventLoopHooks, MiddlewareMixin):
    def process_request(self, request: HttpRequest) -> HttpResponse | None:
        limit = limit_for(request.path)
        length = _content_length(request.META.get("CONTENT_LENGTH"))
        if limit is not None and length is not None and length > limit:
            return JsonResponse(refusal(limit), status=413)
        return None

    def process_exception(self, request: HttpRequest, exception: Exception) -> HttpResponse | None:
        return too_big(exception)


def too_big(exception: Exception) -> HttpResponse | None:
    """The 413 for Django's own refusal of a form (too big, too many fields); None for
    any other exception."""
    if isinstance(exception, RequestDataTooBig):
        return JsonResponse(refusal(int(settings.DATA_UPLOAD_MAX_MEMORY_SIZE)), status=413)
    if isinstance(exception, TooManyFieldsSent):
        body = refusal(0)
        body["error"] = (
            f"The request has more than {settings.DATA_UPLOAD_MAX_NUMBER_FIELDS} fields; "
            "nothing was stored."
        )
        return JsonResponse(body, status=413)
    return None


class BodyLimitASGI:
    """Wraps the HTTP application: a body past its address's limit never reaches Django."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: dict, receive, send) -> None:  # type: ignore[no-untyped-def]
        limit = limit_for(scope.get("path", "")) if scope["type"] == "http" else None
        # Uploads, and bodies larger than the default, are let in only from whom may send
        # them (config/uploadgate.py).
        decide = uploadgate.gate_for(scope, limit)
        if decide is None:
            await self.limited(scope, receive, send, limit)
            return

        async def admitted(scope: dict, receive, send) -> None:  # type: ignore[no-untyped-def]
            await self.limited(scope, receive, send, limit)

        await uploadgate.guard(scope, receive, send, admitted, decide)

    async def limited(self, scope: dict, receive, send, limit: int | None) -> None:  # type: ignore[no-untyped-def]
        if limit is None and scope["method"] != "POST":
            limit = int(settings.REQUEST_BODY_MAX_BYTES)  # an upload address takes only POSTs
        if limit is None:  # the endpoint's own limit (logs/asgi.py)
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        length = _content_length(headers.get(b"content-length"))
        if length is not None and length > limit:
            await _refuse(send, limit)
            return
        state = {"received": 0, "over": False, "started": False}

        async def limited_receive() -> dict:
            if state["over"]:
                return {"type": "http.disconnect"}
            message = await receive()
            if message["type"] == "http.request":
                state["received"] += len(message.get("body", b""))
                if state["received"] > limit:
                    state["over"] = True
                    return {"type": "http.disconnect"}
            return message

        async def tracking_send(message: dict) -> None:
            if message["type"] == "http.response.start":
                state["started"] = True
            await send(message)

        await self.app(scope, limited_receive, tracking_send)
        if state["over"] and not state["started"]:
            await _refuse(send, limit)


async def _refuse(send, limit: int) -> None:  # type: ignore[no-untyped-def]
    body = json.dumps(refusal(limit)).encode()
    headers = [(b"content-type", b"application/json"), (b"connection", b"close"),
               (b"content-length", str(len(body)).encode())]  # fmt: skip
    await send({"type": "http.response.start", "status": 413, "headers": headers})
    await send({"type": "http.response.body", "body": body})

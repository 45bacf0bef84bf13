"""Refusing oversized log uploads before Django reads their body (ASGI).

Django's ASGI handler spools the whole request body to a temporary file before any view
runs, so under uvicorn the view's checks (`uploads.py`) only see a 5 GB upload after it
has been received in full. This middleware wraps the HTTP application: a POST to the
upload path that announces more than the limit gets 413 at once, and a body that grows
past it (chunked, or a lying Content-Length) is cut off — the app sees the client go
away and the client gets 413.

Wire it in `config/asgi.py`: `"http": UploadLimitMiddleware(django_asgi_app)`.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable

from django.conf import settings

from logs.uploads import MULTIPART_SLACK_BYTES, UploadTooLarge

Scope = dict
Message = dict
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

UPLOAD_PATH = "/api/v1/logs/"


def log_upload_limit() -> int:
    return int(settings.LOG_UPLOAD_MAX_BYTES)


class UploadLimitMiddleware:
    """POSTs to `path` limited to `limit()` bytes (the log upload limit by default; the
    map-tile upload of the admin wraps another one around it with its own)."""

    def __init__(
        self, app: ASGIApp, *, path: str = UPLOAD_PATH, limit: Callable[[], int] = log_upload_limit
    ) -> None:
        self.app = app
        self.path = path
        self.limit = limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "POST" or scope["path"] != self.path:
            await self.app(scope, receive, send)
            return
        limit = self.limit()
        allowed = limit + MULTIPART_SLACK_BYTES
        length = _content_length(scope)
        if length is not None and length > allowed:
            await _refuse(send, limit)
            return
        received = 0
        over = False
        started = False

        async def limited_receive() -> Message:
            nonlocal received, over
            if over:
                return {"type": "http.disconnect"}
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > allowed:
                    over = True
                    return {"type": "http.disconnect"}
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        await self.app(scope, limited_receive, tracking_send)
        if over and not started:
            await _refuse(send, limit)


def _content_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", []):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None


async def _refuse(send: Send, limit: int) -> None:
    error = UploadTooLarge(limit)
    body = json.dumps({"error": str(error.detail), "code": "too_large", "fields": {}}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 413,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                (b"connection", b"close"),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})

"""An address or query holding a NUL character answers 400 before any view runs, and a
websocket handshake to one is refused (close code 4400) before any consumer runs.

PostgreSQL's text cannot hold NUL (psycopg refuses such a parameter), and no drone id,
slug, username, search or filter of the API or the pages can contain one: passed on, it
would fail inside a query as a server error. Bodies are checked by their own fields
(DRF's and Django's character fields refuse NUL).
"""

from __future__ import annotations

from collections.abc import Callable
from urllib.parse import unquote_plus

from django.http import HttpRequest, HttpResponse, JsonResponse
from django.utils.deprecation import MiddlewareMixin

from config.middleware import EventLoopHooks

NUL = "\x00"
CLOSE_BAD_REQUEST = 4400


def holds_nul(path: str, query_string: str) -> bool:
    """Whether the decoded path or query string holds a NUL character."""
    return NUL in path or NUL in unquote_plus(query_string)


class NulInUrlMiddleware(EventLoopHooks, MiddlewareMixin):
    def process_request(self, request: HttpRequest) -> HttpResponse | None:
        if not holds_nul(request.path, request.META.get("QUERY_STRING", "")):
            return None
        return JsonResponse(
            {
                "error": "The address or its query holds a NUL character; nothing was done.",
                "code": "nul_character",
                "fields": {},
            },
            status=400,
        )


class NulInUrlASGI:
    """Wraps the websocket application (config/asgi.py)."""

    def __init__(self, app: Callable) -> None:
        self.app = app

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        if holds_nul(scope.get("path", ""), scope.get("query_string", b"").decode("latin-1")):
            await receive()  # the handshake's `websocket.connect`
            await send({"type": "websocket.close", "code": CLOSE_BAD_REQUEST})
            return
        await self.app(scope, receive, send)

"""A request whose address, query or page form holds a NUL character answers 400 before
any view runs, and a websocket handshake to such an address is refused (close code 4400)
before any consumer runs.

PostgreSQL's text cannot hold NUL (psycopg refuses such a parameter), and no drone id,
slug, serial, username, name, search or filter can contain one: passed on, it would fail
inside a query as a server error. The API's bodies are checked by its parsers
(config/parsers.py).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any
from urllib.parse import unquote_plus

from asgiref.sync import iscoroutinefunction, sync_to_async
from django.core.exceptions import RequestDataTooBig, TooManyFieldsSent
from django.http import HttpRequest, HttpResponse, JsonResponse, QueryDict
from django.utils.deprecation import MiddlewareMixin

from config.bodylimits import too_big
from config.middleware import EventLoopHooks

NUL = "\x00"
CLOSE_BAD_REQUEST = 4400


def holds_nul(path: str, query_string: str) -> bool:
    """Whether the decoded path or query string holds a NUL character."""
    return NUL in path or NUL in unquote_plus(query_string)


def value_holds_nul(value: Any) -> bool:
    """Whether any string of a parsed body, key or value at any depth, holds NUL."""
    waiting = [value]
    while waiting:
        item = waiting.pop()
        if isinstance(item, str):
            if NUL in item:
                return True
        elif isinstance(item, QueryDict):
            waiting.extend(item.keys())
            waiting.extend(v for _, values in item.lists() for v in values)
        elif isinstance(item, dict):
            waiting.extend(item.keys())
            waiting.extend(item.values())
        elif isinstance(item, list):
            waiting.extend(item)
    return False


def _refusal() -> JsonResponse:
    return JsonResponse(
        {
            "error": "The address, its query or the form holds a NUL character; nothing was done.",
            "code": "nul_character",
            "fields": {},
        },
        status=400,
    )


def _checks_form(request: HttpRequest, callback: Callable) -> bool:
    return request.method == "POST" and not getattr(callback, "csrf_exempt", False)


class NulCharacterMiddleware(EventLoopHooks, MiddlewareMixin):
    """The address and query of every request; the form fields of a POST to a page (a view
    that checks CSRF tokens, whose form CsrfViewMiddleware reads anyway; the API's views
    are exempt and parse their bodies with config/parsers.py)."""

    def __init__(self, get_response: Callable) -> None:
        super().__init__(get_response)
        if iscoroutinefunction(get_response):
            self.process_view = self._aprocess_view

    def process_request(self, request: HttpRequest) -> HttpResponse | None:
        if holds_nul(request.path, request.META.get("QUERY_STRING", "")):
            return _refusal()
        return None

    def process_view(
        self, request: HttpRequest, callback: Callable, args: tuple, kwargs: dict
    ) -> HttpResponse | None:
        if not _checks_form(request, callback):
            return None
        try:
            form = request.POST
        except (RequestDataTooBig, TooManyFieldsSent) as exc:
            return too_big(exc)  # as the view's own reading would answer
        return _refusal() if value_holds_nul(form) else None

    async def _aprocess_view(
        self, request: HttpRequest, callback: Callable, args: tuple, kwargs: dict
    ) -> HttpResponse | None:
        if not _checks_form(request, callback):
            return None
        # Reading the form may spool an upload to disk: a thread's work.
        check = type(self).process_view  # the class's hook; this instance's is this method
        return await sync_to_async(check, thread_sensitive=True)(
            self, request, callback, args, kwargs
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

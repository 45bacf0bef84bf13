"""Django's stock middleware, run in the event loop under ASGI.

Django runs every hook of a `MiddlewareMixin` in a worker thread when it serves a request
asynchronously: with seven stock middlewares that is about a dozen trips to a thread and
back on every request, a command's round trip included, for hooks that only read headers
and cookies. The classes here run those hooks in the event loop and go to a thread only
when a hook may touch the database or parse a body:

- the session is saved (it was modified, or SESSION_SAVE_EVERY_REQUEST);
- messages were read or added (their storage may load or write the session);
- a form is checked for its CSRF token (reading `request.POST` parses the body, which may
  be a large upload), or the CSRF secret lives in the session.

The settings name Django's own classes (`manage.py check --deploy` looks for them by
name); `EventLoopASGIHandler`, the ASGI entry point's handler, loads the variant of each.
Under WSGI and the test clients nothing changes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from asgiref.sync import iscoroutinefunction, sync_to_async
from django.conf import settings
from django.contrib.auth.middleware import AuthenticationMiddleware as _Authentication
from django.contrib.messages.middleware import MessageMiddleware as _Messages
from django.contrib.sessions.middleware import SessionMiddleware as _Sessions
from django.core import signals
from django.core.handlers.asgi import ASGIHandler
from django.db import close_old_connections, reset_queries
from django.http import HttpRequest, HttpResponse
from django.middleware.clickjacking import XFrameOptionsMiddleware as _XFrameOptions
from django.middleware.common import CommonMiddleware as _Common
from django.middleware.csrf import CsrfViewMiddleware as _Csrf
from django.middleware.security import SecurityMiddleware as _Security

from config.request_threads import RequestThreads

SAFE_METHODS = ("GET", "HEAD", "OPTIONS", "TRACE")


class EventLoopHooks:
    """For a `MiddlewareMixin`: its hooks run in the event loop unless `*_needs_thread`
    says the call at hand may block."""

    def request_needs_thread(self, request: HttpRequest) -> bool:
        return False

    def response_needs_thread(self, request: HttpRequest, response: HttpResponse) -> bool:
        return False

    async def __acall__(self, request: HttpRequest) -> HttpResponse:
        response = None
        if hasattr(self, "process_request"):
            response = await self._run(
                self.request_needs_thread(request), self.process_request, request
            )
        response = response or await self.get_response(request)  # type: ignore[attr-defined]
        if hasattr(self, "process_response"):
            response = await self._run(
                self.response_needs_thread(request, response),
                self.process_response,
                request,
                response,
            )
        return response

    @staticmethod
    async def _run(in_thread: bool, hook: Callable, *args: Any) -> Any:
        if in_thread:
            return await sync_to_async(hook, thread_sensitive=True)(*args)
        return hook(*args)


class SecurityMiddleware(EventLoopHooks, _Security):
    pass


class CommonMiddleware(EventLoopHooks, _Common):
    pass


class AuthenticationMiddleware(EventLoopHooks, _Authentication):
    """Sets a lazy `request.user`: the session and user are loaded on first use, by
    whoever uses them (a view in its thread)."""


class XFrameOptionsMiddleware(EventLoopHooks, _XFrameOptions):
    pass


class SessionMiddleware(EventLoopHooks, _Sessions):
    def response_needs_thread(self, request: HttpRequest, response: HttpResponse) -> bool:
        session = getattr(request, "session", None)
        if session is None:
            return False
        return (session.modified or settings.SESSION_SAVE_EVERY_REQUEST) and not (
            session.is_empty()
        )


class MessageMiddleware(EventLoopHooks, _Messages):
    def response_needs_thread(self, request: HttpRequest, response: HttpResponse) -> bool:
        storage = getattr(request, "_messages", None)
        return storage is not None and (storage.used or storage.added_new)


class CsrfViewMiddleware(EventLoopHooks, _Csrf):
    def __init__(self, get_response: Callable) -> None:
        super().__init__(get_response)
        if iscoroutinefunction(get_response):
            # Django adapts a synchronous process_view with a trip to a thread; this one
            # decides first whether the check needs one.
            self.process_view = self._aprocess_view

    def request_needs_thread(self, request: HttpRequest) -> bool:
        return bool(settings.CSRF_USE_SESSIONS)

    def response_needs_thread(self, request: HttpRequest, response: HttpResponse) -> bool:
        return bool(settings.CSRF_USE_SESSIONS)

    async def _aprocess_view(
        self, request: HttpRequest, callback: Callable, args: tuple, kwargs: dict
    ) -> HttpResponse | None:
        in_thread = settings.CSRF_USE_SESSIONS or not (
            request.method in SAFE_METHODS or getattr(callback, "csrf_exempt", False)
        )
        check = type(self).process_view  # the class's hook; this instance's is this method
        return await self._run(in_thread, check, self, request, callback, args, kwargs)


def _path(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


# Django's middleware as the settings name it → its event-loop variant here.
EVENT_LOOP_VARIANTS = {
    _path(stock): _path(variant)
    for stock, variant in (
        (_Security, SecurityMiddleware),
        (_Common, CommonMiddleware),
        (_Authentication, AuthenticationMiddleware),
        (_XFrameOptions, XFrameOptionsMiddleware),
        (_Sessions, SessionMiddleware),
        (_Messages, MessageMiddleware),
        (_Csrf, CsrfViewMiddleware),
    )
}


# Django's own `request_started` receivers, which look after the request thread's database
# connection: Django sends them to that thread on a trip of their own before the
# middleware runs. Here they run at the start of the request's first synchronous call, in
# the same thread, and a request that never needs the thread (nor its connection) skips
# them; `request_finished` is unchanged.
THREAD_RECEIVERS = (reset_queries, close_old_connections)


def _request_started_in_thread() -> None:
    for receiver in THREAD_RECEIVERS:
        receiver()


class EventLoopASGIHandler(ASGIHandler):
    """Django's ASGI handler with the event-loop variant of each of Django's middleware,
    and each request's synchronous work on a thread kept from an earlier request
    (config.request_threads) rather than on a new one, its `request_started` database
    receivers run there at its first call (THREAD_RECEIVERS)."""

    def __init__(self) -> None:
        super().__init__()
        self.threads = RequestThreads()
        for receiver in THREAD_RECEIVERS:
            signals.request_started.disconnect(receiver)

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            raise ValueError(f"Django can only handle ASGI/HTTP connections, not {scope['type']}.")
        async with self.threads.context(before_first_call=_request_started_in_thread):
            await self.handle(scope, receive, send)

    def load_middleware(self, is_async: bool = False) -> None:
        named = settings.MIDDLEWARE
        # Swapped while the chain is built, once, before the first request.
        settings.MIDDLEWARE = [EVENT_LOOP_VARIANTS.get(path, path) for path in named]
        try:
            super().load_middleware(is_async)
        finally:
            settings.MIDDLEWARE = named

"""A DRF APIView whose handlers may be coroutines, for requests that wait on a drone.

Under ASGI, sync views share one thread: a command waiting 15 s for a reply would stall
the whole site. This keeps DRF's authentication, CSRF, permissions, content negotiation,
error shape and OpenAPI schema (drf-spectacular reads the class), runs those steps in a
worker thread, and awaits the handler on the event loop.

A JSON answer is rendered on the event loop (Django would take a rendered DRF response to
a thread once more), and work the handler put in `after_answer` runs after the answer has
been sent, in the request's thread.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Callable
from typing import Any

from asgiref.sync import markcoroutinefunction, sync_to_async
from django.http import HttpRequest, HttpResponse
from rest_framework.renderers import JSONRenderer
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

log = logging.getLogger(__name__)


class Answered(HttpResponse):
    """A rendered API response; `after_answer` runs when the server closes it, once sent.

    `data` is the DRF response's, for callers that read it (the test client's users)."""

    def __init__(self, response: Response, after_answer: list[Callable[[], None]]) -> None:
        super().__init__(response.content, status=response.status_code)
        for header, value in response.items():
            self[header] = value
        self.cookies = response.cookies
        self.data = response.data
        self.after_answer = after_answer

    def close(self) -> None:
        run_after_answer(self.after_answer)
        self.after_answer = []
        super().close()


def run_after_answer(jobs: list[Callable[[], None]]) -> None:
    """Each job in turn; one that fails is logged and the others still run."""
    for job in jobs:
        try:
            job()
        except Exception:  # noqa: BLE001 - the answer is out; the others still run
            log.exception("work after answering %r failed", job)


async def rendered(response: HttpResponse, after_answer: list[Callable[[], None]]) -> HttpResponse:
    """JSON is rendered here; another renderer (the browsable API) in a thread. A plain
    Django response is returned as it is, its follow-up work done first."""
    if not isinstance(response, Response):
        for job in after_answer:
            await sync_to_async(job)()
        return response
    if isinstance(getattr(response, "accepted_renderer", None), JSONRenderer):
        response.render()
    else:
        await sync_to_async(response.render)()
    return Answered(response, after_answer)


class AsyncAPIView(APIView):
    # Work a handler leaves for after its answer is sent (a log entry, for one).
    after_answer: list[Callable[[], None]]

    @classmethod
    def as_view(cls, **initkwargs: Any):  # type: ignore[no-untyped-def]
        sync_view = super().as_view(**initkwargs)

        async def view(request: HttpRequest, *args: Any, **kwargs: Any) -> Response:
            self = cls(**initkwargs)
            self.setup(request, *args, **kwargs)
            return await self.adispatch(request, *args, **kwargs)

        # What DRF's view function carries, so the router, CSRF and the schema see a DRF view.
        for name in ("cls", "initkwargs", "view_class", "view_initkwargs", "csrf_exempt"):
            if hasattr(sync_view, name):
                setattr(view, name, getattr(sync_view, name))
        view.__doc__ = cls.__doc__
        view.__name__ = cls.__name__
        return markcoroutinefunction(view)

    def _prepare(self, request: Request, *args: Any, **kwargs: Any) -> None:
        """The synchronous part: authenticate (touches the database), check, parse."""
        self.initial(request, *args, **kwargs)
        if request.method not in ("GET", "HEAD", "OPTIONS"):
            request.data  # noqa: B018 - parse now, in this thread, not on the event loop

    async def adispatch(self, request: HttpRequest, *args: Any, **kwargs: Any) -> Response:
        self.args = args
        self.kwargs = kwargs
        self.after_answer = []
        drf_request = self.initialize_request(request, *args, **kwargs)
        self.request = drf_request
        self.headers = self.default_response_headers
        try:
            await sync_to_async(self._prepare)(drf_request, *args, **kwargs)
            method = drf_request.method.lower()
            if method in self.http_method_names and hasattr(self, method):
                handler = getattr(self, method)
            else:
                handler = self.http_method_not_allowed
            if inspect.iscoroutinefunction(handler):
                response = await handler(drf_request, *args, **kwargs)
            else:
                response = await sync_to_async(handler)(drf_request, *args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - DRF turns it into the API's error shape
            response = await sync_to_async(self.handle_exception)(exc)
        self.response = self.finalize_response(drf_request, response, *args, **kwargs)
        return await rendered(self.response, self.after_answer)

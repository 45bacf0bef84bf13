"""A request that meets a database or Redis outage answers 503 with Retry-After, not 500.

The rule: a service that is away for a while (PostgreSQL or Redis restarting, a failover)
is the server's temporary condition, which HTTP names 503 Service Unavailable, with
Retry-After telling the client when to ask again (RFC 9110 §15.6.4, §10.2.3); 500 would
say the request itself broke the server. The body is the API's error shape
(config/api.py): {"error", "code", "fields"}.

Where: Django turns an exception raised anywhere under the outermost middleware (a view,
or a middleware reading the session or the user) into a 500 response at that layer, and
sends `got_request_exception` first. The receiver marks the request when the exception is
a lost connection; `outage_middleware`, first in MIDDLEWARE, answers 503 for a marked
request instead of the 500 built below it. Nothing else changes: other errors stay 500.

Stale connections after a restart are not outages: the pool checks a connection before
lending it (config/env.py), so the first request after PostgreSQL comes back succeeds.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import kombu.exceptions
import psycopg
import redis.exceptions
from asgiref.sync import iscoroutinefunction
from django.core.signals import got_request_exception
from django.db import utils as db_utils
from django.http import HttpRequest, HttpResponse, JsonResponse
from django.utils.decorators import sync_and_async_middleware

# Seconds a client waits before asking again: a PostgreSQL or Redis restart takes a few.
RETRY_AFTER_S = 5
# What a lost or refused connection raises: Django's database errors (psycopg's wrapped),
# psycopg's own (the ingest's and the telemetry queries' connections), redis-py's, and
# kombu's when a task cannot be sent to the Celery broker.
OUTAGE_ERRORS: tuple[type[BaseException], ...] = (
    db_utils.OperationalError,
    db_utils.InterfaceError,
    psycopg.OperationalError,
    psycopg.InterfaceError,
    redis.exceptions.ConnectionError,
    redis.exceptions.TimeoutError,
    kombu.exceptions.OperationalError,
)
_MARK = "_skyhive_outage"


def is_outage(exc: BaseException | None) -> bool:
    """Whether `exc`, or an exception it was raised from, is a lost connection."""
    while exc is not None:
        if isinstance(exc, OUTAGE_ERRORS):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def unavailable() -> JsonResponse:
    response = JsonResponse(
        {"error": "A service the server needs is briefly unavailable; try again.",
         "code": "service_unavailable", "fields": {}},
        status=503,
    )  # fmt: skip
    response["Retry-After"] = str(RETRY_AFTER_S)
    return response


def _mark(sender: Any, request: HttpRequest | None = None, **kwargs: Any) -> None:
    if request is not None and is_outage(sys.exc_info()[1]):
        setattr(request, _MARK, True)


got_request_exception.connect(_mark, dispatch_uid="config.outage.mark")


def _answer(request: HttpRequest, response: HttpResponse) -> HttpResponse:
    if response.status_code == 500 and getattr(request, _MARK, False):
        return unavailable()
    return response


@sync_and_async_middleware
def outage_middleware(
    get_response: Callable[[HttpRequest], Any],
) -> Callable[[HttpRequest], Any]:
    if iscoroutinefunction(get_response):

        async def middleware(request: HttpRequest) -> HttpResponse:
            return _answer(request, await get_response(request))

        return middleware

    def sync_middleware(request: HttpRequest) -> HttpResponse:
        return _answer(request, get_response(request))

    return sync_middleware

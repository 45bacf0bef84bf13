"""The audit trail: who did what, when, from where, and the outcome, per organisation.

Entries are only ever added (models.AuditEvent refuses changes). The request being
served is kept in a context variable by AuditContextMiddleware, so code that has no
request at hand (signal receivers on the command log, mission events, envelope changes)
still records the caller and their address.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from datetime import date, datetime, time
from typing import Any

from asgiref.sync import iscoroutinefunction, markcoroutinefunction
from django.http import HttpRequest, HttpResponse
from django.utils import timezone

from config.throttling import client_address
from fleet.models import Membership

from .models import AuditEvent

_request: ContextVar[HttpRequest | None] = ContextVar("audit_request", default=None)

Kind = AuditEvent.Kind


class AuditContextMiddleware:
    """Makes the request being served known to `record` (sync and async views)."""

    sync_capable = True
    async_capable = True

    def __init__(self, get_response: Callable) -> None:
        self.get_response = get_response
        self.is_async = iscoroutinefunction(get_response)
        if self.is_async:
            markcoroutinefunction(self)

    def __call__(self, request: HttpRequest) -> Any:
        if self.is_async:
            return self._acall(request)
        with serving(request):
            return self.get_response(request)

    async def _acall(self, request: HttpRequest) -> HttpResponse:
        with serving(request):
            return await self.get_response(request)


@contextmanager
def serving(request: HttpRequest) -> Iterator[None]:
    """Within it, `record` knows the request (its user and address)."""
    token = _request.set(request)
    try:
        yield
    finally:
        _request.reset(token)


def current_request() -> HttpRequest | None:
    return _request.get()


def _actor_of(request: HttpRequest | None) -> Any | None:
    user = getattr(request, "user", None) if request is not None else None
    return user if user is not None and user.is_authenticated else None


def record(
    organisation_ids: Iterable[int] | int,
    kind: str,
    action: str,
    *,
    target: str = "",
    outcome: str = "ok",
    actor: Any = None,
    detail: dict | None = None,
) -> None:
    """Add one entry per organisation; the actor defaults to the request's user."""
    request = current_request()
    actor = actor if actor is not None else _actor_of(request)
    ids = [organisation_ids] if isinstance(organisation_ids, int) else list(organisation_ids)
    entries = [
        AuditEvent(
            organisation_id=organisation_id,
            actor=actor if getattr(actor, "pk", None) else None,
            actor_name=actor.get_username() if actor is not None else "",
            kind=kind,
            action=action[:60],
            target=str(target)[:200],
            outcome=outcome,
            ip=client_address(request) if request is not None else None,
            detail=detail or {},
        )
        for organisation_id in ids
    ]
    if len(entries) == 1:
        entries[0].save()  # one INSERT: bulk_create would wrap it in a transaction of its own
    else:
        AuditEvent.objects.bulk_create(entries)


def organisation_ids_of(user: Any) -> list[int]:
    return list(Membership.objects.filter(user=user).values_list("organisation_id", flat=True))


# -- reading -----------------------------------------------------------------------------


def _day(value: str | None) -> date | None:
    try:
        return date.fromisoformat(value) if value else None
    except ValueError:
        return None


def filtered(organisation: Any, params: Any):  # type: ignore[no-untyped-def]
    """The organisation's entries matching `actor`, `kind`, `from` and `to` (dates)."""
    events = AuditEvent.objects.filter(organisation=organisation)
    if params.get("actor"):
        events = events.filter(actor_name__iexact=params["actor"].strip())
    if params.get("kind") in Kind.values:
        events = events.filter(kind=params["kind"])
    start, end = _day(params.get("from")), _day(params.get("to"))
    zone = timezone.get_current_timezone()
    if start:
        events = events.filter(at__gte=datetime.combine(start, time.min, zone))
    if end:
        events = events.filter(at__lte=datetime.combine(end, time.max, zone))
    return events


CSV_COLUMNS = ("at", "actor", "kind", "action", "target", "outcome", "ip", "detail")


def csv_rows(events: Any, *, with_ip: bool) -> Iterator[list[str]]:
    yield list(CSV_COLUMNS)
    for event in events.iterator(chunk_size=1000):
        yield [
            event.at.isoformat(),
            event.actor_name,
            event.kind,
            event.action,
            _cell(event.target),
            event.outcome,
            (event.ip or "") if with_ip else "",
            _cell(json.dumps(event.detail, sort_keys=True)),
        ]


def _cell(text: str) -> str:
    """Text a spreadsheet will not run as a formula (CSV injection)."""
    return "'" + text if text[:1] in ("=", "+", "-", "@") else text

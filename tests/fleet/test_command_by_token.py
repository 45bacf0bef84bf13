"""The command route (config/command_route.py): a token's command that passes every check
is answered before Django's request cycle, exactly as the API view answers it; every
other request reaches Django untouched. Real broker, drone and database."""

from __future__ import annotations

import json
from datetime import timedelta

import pytest
from asgiref.sync import sync_to_async
from channels.testing import HttpCommunicator
from django.db import connection
from django.utils import timezone
from rest_framework.authtoken.models import Token as LegacyToken

from accounts import tokens
from accounts.models import ApiToken, AuditEvent
from config import asyncdb
from config.command_route import CommandRoute
from config.middleware import EventLoopASGIHandler
from fleet.models import CommandLog, Drone

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.asyncio]

ARM = {"command": "arm", "params": {}}


class Django:
    """The Django handler behind the route, counting the requests that reach it."""

    def __init__(self) -> None:
        self.handler = EventLoopASGIHandler()
        self.calls = 0

    async def __call__(self, scope, receive, send):  # type: ignore[no-untyped-def]
        self.calls += 1
        await self.handler(scope, receive, send)


@pytest.fixture
def django_app():  # type: ignore[no-untyped-def]
    return Django()


@pytest.fixture
def key(world_tx) -> str:  # type: ignore[no-untyped-def]
    return tokens.issue(world_tx.operator, name="route").key


async def _post(app, key, body=ARM, drone_id="ACME_1", headers=(), path="", chunked=False):  # type: ignore[no-untyped-def]
    content = json.dumps(body).encode()
    length = [] if chunked else [(b"content-length", str(len(content)).encode())]
    communicator = HttpCommunicator(
        app,
        "POST",
        path or f"/api/v1/drones/{drone_id}/commands/",
        body=content,
        headers=[
            (b"host", b"testserver"),
            (b"content-type", b"application/json"),
            (b"authorization", f"Token {key}".encode()),
            *length,
            *headers,
        ],
    )
    response = await communicator.get_response(timeout=20)
    await communicator.wait(20)  # and the work after the answer (the log entry)
    kind = dict(response["headers"]).get(b"Content-Type", b"")
    body = json.loads(response["body"]) if kind == b"application/json" else response["body"]
    return response["status"], response["headers"], body


def _comparable(headers: list) -> dict:
    return {k.lower(): v for k, v in headers if k.lower() != b"content-length"}


def _same_answer(body: dict) -> dict:
    return {k: v for k, v in body.items() if k != "request_id"}


async def test_a_command_that_passes_every_check_is_answered_without_django(
    key, ready_link, responding_drone, django_app
):
    status, _, body = await _post(CommandRoute(django_app), key)
    assert django_app.calls == 0
    assert status == 200 and body["ok"] is True and body["result"] == {"echo": {}}
    assert [r["request_id"] for r in responding_drone.requests] == [body["request_id"]]


async def test_its_answer_log_and_audit_are_the_views_own(
    world_tx, key, ready_link, responding_drone, django_app, settings
):
    route = CommandRoute(django_app)
    taken = await _post(route, key)
    settings.COMMAND_ROUTE = False
    viewed = await _post(route, key)
    assert django_app.calls == 1  # the second one only
    assert taken[0] == viewed[0] == 200, viewed
    assert _same_answer(taken[2]) == _same_answer(viewed[2])
    assert _comparable(taken[1]) == _comparable(viewed[1])

    def logged(request_id: str) -> tuple:
        entry = CommandLog.objects.get(request_id=request_id)
        audit = AuditEvent.objects.get(detail__request_id=request_id)
        return (
            (entry.command, entry.outcome, entry.user_id, entry.response["ok"]),
            (audit.action, audit.outcome, audit.actor_id, audit.ip, audit.target),
        )

    by_route = await sync_to_async(logged)(taken[2]["request_id"])
    by_view = await sync_to_async(logged)(viewed[2]["request_id"])
    assert by_route == by_view
    assert by_route[0] == ("arm", "ok", world_tx.operator.pk, True)


async def test_the_token_is_marked_used(key, ready_link, responding_drone, django_app):
    await _post(CommandRoute(django_app), key)
    token = await ApiToken.objects.aget(key_hash=tokens.digest(key))
    assert token.last_used_at is not None


def _legacy(world):  # type: ignore[no-untyped-def]
    return LegacyToken.objects.create(user=world.operator).key


def _read_only(world):  # type: ignore[no-untyped-def]
    return tokens.issue(world.operator, name="reader", scope="read").key


def _revoked(world):  # type: ignore[no-untyped-def]
    issued = tokens.issue(world.operator, name="gone")
    tokens.revoke(issued.token)
    return issued.key


def _expired(world):  # type: ignore[no-untyped-def]
    issued = tokens.issue(world.operator, name="old")
    ApiToken.objects.filter(pk=issued.token.pk).update(expires_at=timezone.now())
    return issued.key


def _inactive(world):  # type: ignore[no-untyped-def]
    key = tokens.issue(world.operator, name="left").key
    type(world.operator).objects.filter(pk=world.operator.pk).update(is_active=False)
    return key


def _viewer(world):  # type: ignore[no-untyped-def]
    return tokens.issue(world.viewer, name="viewer").key


def _offline(world):  # type: ignore[no-untyped-def]
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    return tokens.issue(world.operator, name="offline").key


def _operator(world):  # type: ignore[no-untyped-def]
    return tokens.issue(world.operator, name="operator").key


# Requests the route leaves to Django: (token maker, request changes).
DECLINED = {
    "legacy token": (_legacy, {}),
    "read-only token": (_read_only, {}),
    "revoked token": (_revoked, {}),
    "expired token": (_expired, {}),
    "inactive user": (_inactive, {}),
    "viewer": (_viewer, {}),
    "offline drone": (_offline, {}),
    "another organisation's drone": (_operator, {"drone_id": "GLOBEX_1"}),
    "unknown drone": (_operator, {"drone_id": "NOBODY_1"}),
    "bad parameter": (_operator, {"body": {"command": "takeoff", "params": {"altitude": "x"}}}),
    "outside the envelope": (
        _operator,
        {"body": {"command": "takeoff", "params": {"altitude": 5000}}},
    ),
    "unknown field": (_operator, {"body": {**ARM, "priority": 1}}),
    "confirmation as text": (_operator, {"body": {**ARM, "confirm_beyond_defaults": "yes"}}),
    "mission hook": (_operator, {"body": {"command": "stopchain", "params": {}}}),
    "a cookie": (_operator, {"headers": [(b"cookie", b"sessionid=x")]}),
    "a query string": (_operator, {"path": "/api/v1/drones/ACME_1/commands/?format=json"}),
    "an HTML answer asked for": (_operator, {"headers": [(b"accept", b"text/html")]}),
    "no Content-Length": (_operator, {"chunked": True}),
    "a repeated header": (_operator, {"headers": [(b"content-type", b"application/json")]}),
}


@pytest.mark.parametrize("case", DECLINED)
async def test_anything_else_is_answered_by_django_as_before(
    case, world_tx, ready_link, responding_drone, django_app, settings
):
    make_key, changes = DECLINED[case]
    key = await sync_to_async(make_key)(world_tx)
    route = CommandRoute(django_app)
    declined = await _post(route, key, **changes)
    assert django_app.calls == 1, "the route answered it itself"
    settings.COMMAND_ROUTE = False
    alone = await _post(route, key, **changes)
    assert declined[0] == alone[0]
    if isinstance(declined[2], dict) and "request_id" not in declined[2]:
        assert declined[2] == alone[2]  # the same refusal, word for word


async def test_a_refusal_is_logged_once(world_tx, ready_link, responding_drone, django_app):
    key = await sync_to_async(_viewer)(world_tx)
    status, _, _ = await _post(CommandRoute(django_app), key)
    assert status == 403
    refused = CommandLog.objects.filter(user=world_tx.viewer, outcome="rejected")
    assert await refused.acount() == 1


async def test_a_host_django_would_refuse_is_left_to_django(
    key, ready_link, responding_drone, django_app, settings
):
    settings.ALLOWED_HOSTS = ["skyhive.example"]
    status, _, _ = await _post(CommandRoute(django_app), key)
    assert (status, django_app.calls) == (400, 1)


async def test_a_lost_database_connection_leaves_the_command_to_django_then_reconnects(
    key, ready_link, responding_drone, django_app
):
    route = CommandRoute(django_app)
    await _post(route, key)
    assert django_app.calls == 0
    backend = asyncdb._current.connection.info.backend_pid  # type: ignore[union-attr]

    def end_it() -> None:
        with connection.cursor() as cursor:
            cursor.execute("SELECT pg_terminate_backend(%s)", [backend])

    await sync_to_async(end_it)()
    status, _, body = await _post(route, key)
    assert (status, body["ok"], django_app.calls) == (200, True, 1)
    await _post(route, key)
    assert django_app.calls == 1  # a fresh connection: the route takes it again


async def test_a_token_made_for_an_organisation_still_commands_its_drones(
    world_tx, ready_link, responding_drone, django_app
):
    issued = await sync_to_async(tokens.issue)(
        world_tx.operator, name="acme only", organisation=world_tx.org, days=1
    )
    status, _, body = await _post(CommandRoute(django_app), issued.key)
    assert (status, body["ok"], django_app.calls) == (200, True, 0)
    assert issued.token.expires_at - timezone.now() < timedelta(days=2)

"""A token's command through the deployed ASGI app (config.asgi): there is one way in,
Django's handler, its middleware and DRF, so every rule of the ordinary path holds for
it. Real broker, drone and database."""

from __future__ import annotations

import json
from datetime import timedelta

import pytest
from asgiref.sync import sync_to_async
from channels.testing import HttpCommunicator
from django.utils import timezone
from rest_framework.authtoken.models import Token as LegacyToken

from accounts import tokens
from accounts.models import ApiToken, AuditEvent
from fleet.models import CommandLog, Drone

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.asyncio]

ARM = {"command": "arm", "params": {}}


@pytest.fixture
def app():  # type: ignore[no-untyped-def]
    from config.asgi import application

    return application


@pytest.fixture
def key(world_tx) -> str:  # type: ignore[no-untyped-def]
    return tokens.issue(world_tx.operator, name="api").key


async def _post(app, key, body=ARM, drone_id="ACME_1", headers=()):  # type: ignore[no-untyped-def]
    content = json.dumps(body).encode()
    communicator = HttpCommunicator(
        app,
        "POST",
        f"/api/v1/drones/{drone_id}/commands/",
        body=content,
        headers=[
            (b"host", b"testserver"),
            (b"content-type", b"application/json"),
            (b"authorization", f"Token {key}".encode()),
            (b"content-length", str(len(content)).encode()),
            *headers,
        ],
    )
    response = await communicator.get_response(timeout=20)
    await communicator.wait(20)  # and the work after the answer (the log entry)
    kind = dict(response["headers"]).get(b"Content-Type", b"")
    body = json.loads(response["body"]) if kind == b"application/json" else response["body"]
    return response["status"], body


async def test_a_token_command_is_answered_with_the_drones_reply(
    app, key, ready_link, responding_drone
):
    status, body = await _post(app, key)
    assert status == 200 and body["ok"] is True and body["result"] == {"echo": {}}
    assert [r["request_id"] for r in responding_drone.requests] == [body["request_id"]]


async def test_the_command_is_logged_and_audited_with_its_sender(
    world_tx, app, key, ready_link, responding_drone
):
    status, body = await _post(app, key)
    assert status == 200, body

    def logged(request_id: str) -> tuple:
        entry = CommandLog.objects.get(request_id=request_id)
        audit = AuditEvent.objects.get(detail__request_id=request_id)
        return (
            (entry.command, entry.outcome, entry.user_id, entry.response["ok"]),
            (audit.actor_id, audit.outcome),
        )

    command, audit = await sync_to_async(logged)(body["request_id"])
    assert command == ("arm", "ok", world_tx.operator.pk, True)
    assert audit == (world_tx.operator.pk, "ok")


async def test_the_token_is_marked_used(app, key, ready_link, responding_drone):
    await _post(app, key)
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


# (token maker, request changes, the status the API answers).
CASES = {
    "legacy token": (_legacy, {}, 200),
    "read-only token": (_read_only, {}, 403),
    "revoked token": (_revoked, {}, 401),
    "expired token": (_expired, {}, 401),
    "inactive user": (_inactive, {}, 401),
    "viewer": (_viewer, {}, 403),
    "offline drone": (_offline, {}, 409),
    "another organisation's drone": (_operator, {"drone_id": "GLOBEX_1"}, 404),
    "unknown drone": (_operator, {"drone_id": "NOBODY_1"}, 404),
    "bad parameter": (
        _operator,
        {"body": {"command": "takeoff", "params": {"altitude": "x"}}},
        400,
    ),
    "outside the envelope": (
        _operator,
        {"body": {"command": "takeoff", "params": {"altitude": 500}}},
        409,
    ),
    "unknown field": (_operator, {"body": {**ARM, "priority": 1}}, 400),
    "confirmation not a boolean": (
        _operator,
        {"body": {**ARM, "confirm_beyond_defaults": [1]}},
        400,
    ),
}


@pytest.mark.parametrize("case", CASES)
async def test_each_rule_of_the_api_holds_for_a_token_command(
    case, world_tx, app, ready_link, responding_drone
):
    make_key, changes, expected = CASES[case]
    key = await sync_to_async(make_key)(world_tx)
    status, body = await _post(app, key, **changes)
    assert status == expected, body
    sent = 1 if expected == 200 else 0
    assert len(responding_drone.requests) == sent


async def test_a_refusal_is_logged_once(world_tx, app, ready_link, responding_drone):
    key = await sync_to_async(_viewer)(world_tx)
    status, _ = await _post(app, key)
    assert status == 403
    refused = CommandLog.objects.filter(user=world_tx.viewer, outcome="rejected")
    assert await refused.acount() == 1


async def test_a_host_django_refuses_sends_nothing(
    app, key, ready_link, responding_drone, settings
):
    settings.ALLOWED_HOSTS = ["skyhive.example"]
    status, _ = await _post(app, key)
    assert (status, responding_drone.requests) == (400, [])


async def test_a_token_made_for_an_organisation_commands_its_drones(
    world_tx, app, ready_link, responding_drone
):
    issued = await sync_to_async(tokens.issue)(
        world_tx.operator, name="acme only", organisation=world_tx.org, days=1
    )
    status, body = await _post(app, issued.key)
    assert (status, body["ok"]) == (200, True)
    assert issued.token.expires_at - timezone.now() < timedelta(days=2)

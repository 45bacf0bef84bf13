"""The second factor an organisation requires, tried from the attacker's side: a session
that owes it mints no token and steers no drone; a borrowed session cannot move the
authenticator to another phone; a new password ends the old tokens and other sessions."""

from __future__ import annotations

import pytest
from asgiref.sync import sync_to_async
from channels.testing import WebsocketCommunicator
from django.test import Client
from django_otp import DEVICE_ID_SESSION_KEY
from django_otp.plugins.otp_totp.models import TOTPDevice
from rest_framework.test import APIClient

from accounts import tokens
from accounts.models import ApiToken, AuditEvent
from fleet.models import CommandLog
from tests.pastview.support import in_own_loop
from tests.support.websocket import connect_websocket, session_cookie

from .test_sign_in import PASSWORD, code, enrol, require_second_factor, signed_in

TELEOP = {"type": "teleop", "forward": 1, "right": 0, "up": 0}
ORIGIN = b"http://127.0.0.1"


def test_a_session_owing_the_second_factor_creates_no_token_on_the_security_page(world):
    require_second_factor(world.org)
    client = signed_in(world.operator)
    refused = client.post("/accounts/security/tokens/", {"name": "steal", "expires_in_days": 5})
    assert refused.status_code == 403
    assert "second factor" in refused.content.decode()
    assert not ApiToken.objects.filter(user=world.operator).exists()
    enrol(client, world.operator)  # the same session, once it gave a code
    made = client.post("/accounts/security/tokens/", {"name": "script", "expires_in_days": 5})
    assert made.status_code == 201 and ApiToken.objects.filter(user=world.operator).count() == 1


def test_the_api_gives_no_token_to_a_user_owing_the_second_factor(world):
    require_second_factor(world.org)
    body = {"username": "operator", "password": PASSWORD}
    response = APIClient().post("/api/v1/token/", body, format="json")
    assert response.status_code == 403 and response.json()["code"] == "second_factor_required"
    assert not ApiToken.objects.filter(user=world.operator).exists()


@pytest.mark.django_db(transaction=True)
@pytest.mark.usefixtures("no_snapshots_from_earlier_tests")
@in_own_loop
async def test_a_session_owing_the_second_factor_cannot_teleoperate(world_tx):
    from config.asgi import application

    await sync_to_async(require_second_factor)(world_tx.org)
    communicator, connected, _ = await connect_websocket("/ws/pastview/ACME_1/", world_tx.operator)
    try:
        assert connected
        hello = await communicator.receive_json_from(timeout=5)
        assert hello["type"] == "hello" and hello["can_operate"] is False
        await communicator.send_json_to(TELEOP)
        reply = await communicator.receive_json_from(timeout=5)
        assert reply["type"] == "teleop" and reply["ok"] is False and reply["sent"] == []
        assert not await sync_to_async(CommandLog.objects.exists)()
    finally:
        await communicator.disconnect()
    # A session that gave its code steers again.
    cookie = await sync_to_async(verified_session)(world_tx.operator)
    communicator = WebsocketCommunicator(
        application, "/ws/pastview/ACME_1/", headers=[(b"origin", ORIGIN), (b"cookie", cookie)]
    )
    try:
        assert (await communicator.connect(timeout=5))[0]
        assert (await communicator.receive_json_from(timeout=5))["can_operate"] is True
    finally:
        await communicator.disconnect()


def verified_session(user) -> bytes:  # type: ignore[no-untyped-def]
    """The cookie of a session that signed in with the user's (new) authenticator."""
    from django.contrib.sessions.backends.db import SessionStore

    device = TOTPDevice.objects.create(user=user, name="phone", confirmed=True)
    key = session_cookie(user).decode().split("=", 1)[1]
    session = SessionStore(session_key=key)
    session[DEVICE_ID_SESSION_KEY] = device.persistent_id
    session.save()
    return f"sessionid={key}".encode()


def test_moving_the_authenticator_asks_for_the_current_code(world):
    client = signed_in(world.operator)
    old = enrol(client, world.operator)
    client.get("/accounts/security/two-factor/")  # a borrowed session starts a new one
    new = TOTPDevice.objects.get(user=world.operator, confirmed=False)
    refused = client.post("/accounts/security/two-factor/", {"code": code(new)})
    assert refused.status_code == 403
    with_password = client.post(
        "/accounts/security/two-factor/", {"code": code(new), "password": PASSWORD}
    )
    assert with_password.status_code == 403  # with one enrolled, only its code will do
    assert list(TOTPDevice.objects.filter(user=world.operator, confirmed=True)) == [old]
    moved = client.post(
        "/accounts/security/two-factor/",
        {"code": code(new, ahead=1), "current_code": code(old, ahead=1)},
    )
    assert moved.status_code == 302
    assert list(TOTPDevice.objects.filter(user=world.operator, confirmed=True)) == [new]


def test_turning_the_authenticator_off_asks_for_its_current_code(world):
    """Off, then on again with a new app, is no way around the current code: without it,
    or with the password or a wrong code, the authenticator stays."""
    client = signed_in(world.operator)
    device = enrol(client, world.operator)
    wrong = f"{(int(code(device)) + 1) % 1_000_000:06d}"
    for proof in ({}, {"password": PASSWORD}, {"code": wrong}):
        client.post("/accounts/security/two-factor/disable/", proof)
        assert list(TOTPDevice.objects.filter(user=world.operator, confirmed=True)) == [device]
    device.refresh_from_db()
    device.throttle_reset()  # the wrong code slowed the device down (django-otp)
    client.post("/accounts/security/two-factor/disable/", {"code": code(device, ahead=1)})
    assert not TOTPDevice.objects.filter(user=world.operator, confirmed=True).exists()


def test_enrolling_without_an_authenticator_asks_for_the_password(world):
    client = signed_in(world.viewer)
    client.get("/accounts/security/two-factor/")
    device = TOTPDevice.objects.get(user=world.viewer, confirmed=False)
    for proof in ({}, {"password": "not the password"}):
        refused = client.post("/accounts/security/two-factor/", {"code": code(device), **proof})
        assert refused.status_code == 403
    assert not TOTPDevice.objects.filter(user=world.viewer, confirmed=True).exists()


def test_a_new_password_revokes_the_tokens_and_ends_the_other_sessions(world):
    key = tokens.issue(world.operator, name="script", organisation=world.org).key
    api = APIClient()
    api.credentials(HTTP_AUTHORIZATION=f"Token {key}")
    assert api.get("/api/v1/drones/").status_code == 200
    elsewhere, here = signed_in(world.operator), signed_in(world.operator)
    assert elsewhere.get("/accounts/security/").status_code == 200
    page = here.get("/accounts/password/").content.decode()
    assert "revokes all your personal API tokens" in page
    new = "a fresh and long passphrase"
    changed = here.post(
        "/accounts/password/",
        {"old_password": PASSWORD, "new_password1": new, "new_password2": new},
    )
    assert changed.status_code == 302
    refused = api.get("/api/v1/drones/")
    assert refused.status_code == 401 and refused.json()["code"] == "token_revoked"
    assert elsewhere.get("/accounts/security/").status_code == 302  # signed out
    assert here.get("/accounts/security/").status_code == 200  # the changing session stays
    assert AuditEvent.objects.filter(action="security.password_change").count() == 1


def test_a_password_reset_revokes_the_tokens_too(world):
    key = tokens.issue(world.viewer, name="script", organisation=world.org).key
    world.viewer.set_password("another long passphrase")
    world.viewer.save()
    api = APIClient()
    api.credentials(HTTP_AUTHORIZATION=f"Token {key}")
    assert api.get("/api/v1/drones/").status_code == 401
    # A sign-in (which may upgrade the stored hash) revokes nothing.
    fresh = tokens.issue(world.viewer, name="again", organisation=world.org)
    Client().post("/accounts/login/", {"username": "viewer", "password": "another long passphrase"})
    fresh.token.refresh_from_db()
    assert fresh.token.revoked_at is None

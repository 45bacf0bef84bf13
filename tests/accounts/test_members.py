"""Organisation admins invite, re-role and remove members; the change holds at once."""

from __future__ import annotations

import re
from datetime import timedelta

import pytest
from asgiref.sync import sync_to_async
from django.contrib.auth.models import User
from django.core import mail
from django.test import Client
from django.utils import timezone
from rest_framework.test import APIClient

from accounts import tokens
from accounts.models import Invitation
from fleet.consumers import CLOSE_FORBIDDEN
from fleet.models import Membership, Role
from runtime.processes import free_port
from tests.support.websocket import connect_websocket

PASSWORD = "correct horse battery staple"


def signed_in(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def invite(admin, email: str, role: str) -> str:  # type: ignore[no-untyped-def]
    """The link of a new invitation, read from the e-mail it sent."""
    response = signed_in(admin).post("/accounts/members/invite/", {"email": email, "role": role})
    assert response.status_code == 302, response.content.decode()
    message = mail.outbox[-1]
    assert message.to == [email]
    return re.search(r"http://testserver(/accounts/invitation/\S+/)", message.body).group(1)


def sign_up(link: str, username: str) -> Client:
    client = Client()
    response = client.post(
        link, {"username": username, "password1": PASSWORD, "password2": PASSWORD}
    )
    assert response.status_code == 302, response.content.decode()
    assert response["Location"] == "/"
    return client


def test_an_admin_invites_and_the_invitee_signs_up_with_the_invited_role(world):
    link = invite(world.owner, "pilot@example.org", Role.OPERATOR)
    client = sign_up(link, "pilot")
    pilot = User.objects.get(username="pilot")
    assert pilot.email == "pilot@example.org"
    assert Membership.objects.get(user=pilot).role == Role.OPERATOR
    assert Membership.objects.get(user=pilot).organisation == world.org
    assert "Operator" in client.get("/").content.decode()
    assert [row["drone_id"] for row in client.get("/fleet/table/").json()["results"]] == ["ACME_1"]


def test_a_used_link_is_refused(world):
    link = invite(world.owner, "pilot@example.org", Role.VIEWER)
    sign_up(link, "pilot")
    again = Client().post(
        link, {"username": "pilot2", "password1": PASSWORD, "password2": PASSWORD}
    )
    assert again.status_code == 410
    assert "already used" in again.content.decode()
    assert not User.objects.filter(username="pilot2").exists()


def test_an_expired_link_is_refused_and_makes_no_account(world):
    link = invite(world.owner, "late@example.org", Role.VIEWER)
    Invitation.objects.update(expires_at=timezone.now() - timedelta(minutes=1))
    assert Client().get(link).status_code == 410
    response = Client().post(
        link, {"username": "late", "password1": PASSWORD, "password2": PASSWORD}
    )
    assert response.status_code == 410 and "expired" in response.content.decode()
    assert not User.objects.filter(username="late").exists()


def test_an_invitee_with_an_account_signs_in_and_joins(world):
    world.outsider.email = "outsider@example.org"
    world.outsider.save()
    link = invite(world.owner, "outsider@example.org", Role.VIEWER)
    assert "sign in" in Client().get(link).content.decode()
    client = signed_in(world.outsider)
    assert client.post(link).status_code == 302
    assert Membership.objects.get(user=world.outsider, organisation=world.org).role == "viewer"
    # Someone else signed in cannot take the invitation.
    other = invite(world.owner, "someone@example.org", Role.ADMIN)
    refused = signed_in(world.viewer).post(other)
    assert refused.status_code == 403
    assert Membership.objects.get(user=world.viewer).role == Role.VIEWER


def test_only_admins_see_and_use_the_members_page(world):
    page = signed_in(world.owner).get("/accounts/members/").content.decode()
    for name in ("owner", "operator", "viewer"):
        assert f'data-member="{name}"' in page
    assert "outsider" not in page
    for user in (world.operator, world.viewer):
        client = signed_in(user)
        assert client.get("/accounts/members/").status_code == 403
        body = {"email": "x@example.org", "role": "admin"}
        assert client.post("/accounts/members/invite/", body).status_code == 403
    assert not Invitation.objects.exists()


def test_an_admin_cannot_touch_another_organisations_members(world):
    theirs = Membership.objects.get(user=world.outsider)
    client = signed_in(world.owner)
    assert (
        client.post(f"/accounts/members/{theirs.pk}/role/", {"role": "viewer"}).status_code == 404
    )
    assert client.post(f"/accounts/members/{theirs.pk}/remove/").status_code == 404
    theirs.refresh_from_db()
    assert theirs.role == Role.ADMIN


def test_a_role_change_takes_effect_on_the_next_request(world):
    viewer = signed_in(world.viewer)
    assert viewer.get("/drones/ACME_1/").content.decode().count("data-command=") == 0
    membership = Membership.objects.get(user=world.viewer)
    response = signed_in(world.owner).post(
        f"/accounts/members/{membership.pk}/role/", {"role": "operator"}
    )
    assert response.status_code == 302
    assert viewer.get("/drones/ACME_1/").content.decode().count("data-command=") > 0


def test_the_last_admin_can_be_neither_demoted_nor_removed(world):
    owner = Membership.objects.get(user=world.owner)
    client = signed_in(world.owner)
    demoted = client.post(f"/accounts/members/{owner.pk}/role/", {"role": "operator"})
    assert demoted.status_code == 409 and "at least one admin" in demoted.content.decode()
    assert client.post(f"/accounts/members/{owner.pk}/remove/").status_code == 409
    owner.refresh_from_db()
    assert owner.role == Role.ADMIN
    # With a second admin, the first may step down.
    operator = Membership.objects.get(user=world.operator)
    client.post(f"/accounts/members/{operator.pk}/role/", {"role": "admin"})
    assert client.post(f"/accounts/members/{owner.pk}/role/", {"role": "viewer"}).status_code == 302


def test_a_bad_invitation_says_why_and_sends_nothing(world):
    client = signed_in(world.owner)
    for body in ({"email": "not-an-address", "role": "viewer"}, {"email": "a@b.org", "role": "x"}):
        response = client.post("/accounts/members/invite/", body)
        assert response.status_code == 400
    assert not mail.outbox and not Invitation.objects.exists()


def test_a_withdrawn_invitation_no_longer_works(world):
    link = invite(world.owner, "gone@example.org", Role.VIEWER)
    invitation = Invitation.objects.get()
    signed_in(world.owner).post(f"/accounts/invitations/{invitation.pk}/revoke/")
    assert Client().get(link).status_code == 410


@pytest.mark.django_db(transaction=True)
async def test_removal_takes_effect_at_once_sockets_tokens_and_pages(world_tx):
    viewer = world_tx.viewer
    key = (await sync_to_async(tokens.issue)(viewer, name="x", organisation=world_tx.org)).key
    viewer_client = await sync_to_async(signed_in)(viewer)
    communicator, connected, _ = await connect_websocket("/ws/fleet/?org=acme", viewer)
    assert connected
    try:
        assert (await communicator.receive_json_from(timeout=5))["type"] == "snapshot"
        membership = await Membership.objects.aget(user=viewer)

        def remove() -> int:
            return (
                signed_in(world_tx.owner)
                .post(f"/accounts/members/{membership.pk}/remove/")
                .status_code
            )

        assert await sync_to_async(remove)() == 302
        closed = await communicator.receive_output(timeout=5)
        assert closed == {"type": "websocket.close", "code": CLOSE_FORBIDDEN}
    finally:
        await communicator.disconnect()
    _, connected, _ = await connect_websocket("/ws/fleet/?org=acme", viewer)
    assert not connected
    page = await sync_to_async(viewer_client.get)("/drones/ACME_1/")
    assert page.status_code == 404
    response = await sync_to_async(APIClient(HTTP_AUTHORIZATION=f"Token {key}").get)("/api/v1/me/")
    assert response.status_code == 401 and response.json()["code"] == "token_revoked"


def test_a_superuser_outside_the_organisation_does_not_manage_its_members(world):
    root = User.objects.create_superuser("root", "root@example.org", PASSWORD)
    client = signed_in(root)
    assert client.get("/accounts/members/").status_code == 403
    theirs = Membership.objects.get(user=world.viewer)
    assert client.post(f"/accounts/members/{theirs.pk}/remove/").status_code == 403
    assert Membership.objects.filter(pk=theirs.pk).exists()


def test_a_demoted_operator_cannot_command_on_the_next_request(world):
    key = tokens.issue(world.operator, name="script", organisation=world.org).key
    client = APIClient(HTTP_AUTHORIZATION=f"Token {key}")
    body = {"command": "arm"}
    url = "/api/v1/drones/ACME_1/commands/"
    assert client.post(url, body, format="json").status_code == 409  # allowed, drone offline
    membership = Membership.objects.get(user=world.operator)
    signed_in(world.owner).post(f"/accounts/members/{membership.pk}/role/", {"role": "viewer"})
    assert client.post(url, body, format="json").status_code == 403


def test_an_invitation_the_mail_server_refuses_is_withdrawn_and_said(world, settings):
    # A mail server nobody listens on: the connection is refused at once.
    settings.EMAIL_BACKEND = "django.core.mail.backends.smtp.EmailBackend"
    settings.EMAIL_HOST, settings.EMAIL_PORT, settings.EMAIL_TIMEOUT = "127.0.0.1", free_port(), 2
    response = signed_in(world.owner).post(
        "/accounts/members/invite/", {"email": "pilot@example.org", "role": "viewer"}
    )
    assert response.status_code == 502
    assert "could not be sent" in response.content.decode()
    assert Invitation.objects.get().state == "revoked"

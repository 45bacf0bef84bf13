"""Signing in: password reset by e-mail, the optional TOTP second factor an organisation
may require, and the record of attempts on the user's security page."""

from __future__ import annotations

import re
import time
import uuid
from datetime import timedelta

from django.core import mail
from django.test import Client
from django.utils import timezone
from django_otp.oath import TOTP
from django_otp.plugins.otp_totp.models import TOTPDevice
from rest_framework.test import APIClient

from accounts.models import OrganisationSettings, SignInAttempt
from fleet.models import Membership

PASSWORD = "correct horse battery staple"
COMMAND = {"command": "arm", "params": {}}


def code(device: TOTPDevice, ahead: int = 0) -> str:
    """The device's code `ahead` time steps from now (each code is accepted once)."""
    totp = TOTP(device.bin_key, device.step, device.t0, device.digits, device.drift)
    totp.time = time.time() + ahead * device.step
    return str(totp.token()).zfill(device.digits)


def signed_in(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def require_second_factor(org) -> None:  # type: ignore[no-untyped-def]
    OrganisationSettings.objects.update_or_create(
        organisation=org, defaults={"require_second_factor": True}
    )


def enrol(client: Client, user) -> TOTPDevice:  # type: ignore[no-untyped-def]
    page = client.get("/accounts/security/two-factor/")
    assert page.status_code == 200 and "<svg" in page.content.decode()
    device = TOTPDevice.objects.get(user=user, confirmed=False)
    assert page.context["secret"] in page.content.decode()
    proof = {"password": PASSWORD}
    wrong = client.post("/accounts/security/two-factor/", {**proof, "code": "000000"})
    assert wrong.status_code == 400
    device.refresh_from_db()
    device.throttling_failure_count = 0  # the wrong code above slows the next try
    device.save()
    right = client.post("/accounts/security/two-factor/", {**proof, "code": code(device)})
    assert right.status_code == 302
    device.refresh_from_db()
    assert device.confirmed
    return device


def command(client: Client):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/drones/ACME_1/commands/", COMMAND, content_type="application/json")


def test_password_reset_round_trip_through_the_mail_outbox(world):
    world.operator.email = "operator@example.org"
    world.operator.save()
    client = Client(REMOTE_ADDR=f"2001:db8::{uuid.uuid4().hex[:4]}")
    response = client.post("/accounts/password/reset/", {"email": "operator@example.org"})
    assert response.status_code == 302
    assert len(mail.outbox) == 1 and mail.outbox[0].to == ["operator@example.org"]
    link = re.search(r"http://testserver(/accounts/password/reset/\S+/)", mail.outbox[0].body)
    form_page = client.get(link.group(1), follow=True)
    assert form_page.status_code == 200 and form_page.context["validlink"]
    new = "a fresh and long passphrase"
    done = client.post(
        form_page.redirect_chain[-1][0], {"new_password1": new, "new_password2": new}
    )
    assert done.status_code == 302 and done["Location"] == "/accounts/password/reset/done/"
    assert (
        Client().post("/accounts/login/", {"username": "operator", "password": new}).status_code
        == 302
    )
    # The link works once.
    assert not Client().get(link.group(1), follow=True).context["validlink"]


def test_an_unknown_address_gets_the_same_answer_and_no_mail(world):
    client = Client(REMOTE_ADDR=f"2001:db8::{uuid.uuid4().hex[:4]}")
    response = client.post("/accounts/password/reset/", {"email": "nobody@example.org"})
    assert response.status_code == 302 and not mail.outbox


def test_an_operator_without_the_required_second_factor_must_enrol_before_commanding(world):
    require_second_factor(world.org)
    client = signed_in(world.operator)
    refused = command(client)
    assert refused.status_code == 403
    assert refused.json()["code"] == "second_factor_required"
    assert client.get("/api/v1/drones/").status_code == 200  # reading still works
    assert "needs-attention" in client.get("/").content.decode()
    assert not world.drone.commands.exists()

    enrol(client, world.operator)
    passed = command(client)  # past authentication: refused only because it is offline
    assert passed.status_code == 409 and "offline" in passed.json()["error"]
    assert "needs-attention" not in client.get("/").content.decode()


def test_the_requirement_spares_viewers_and_other_organisations(world):
    require_second_factor(world.org)
    assert "needs-attention" not in signed_in(world.viewer).get("/").content.decode()
    refused = command(Client())  # anonymous
    assert refused.status_code in (401, 403)
    response = signed_in(world.outsider).post(
        "/api/v1/drones/GLOBEX_1/commands/", COMMAND, content_type="application/json"
    )
    assert response.status_code == 409  # globex requires nothing


def test_no_token_for_a_user_who_owes_the_required_second_factor(world):
    require_second_factor(world.org)
    body = {"username": "operator", "password": PASSWORD}
    response = APIClient().post("/api/v1/token/", body, format="json")
    assert response.status_code == 403 and response.json()["code"] == "second_factor_required"


def test_signing_in_with_an_authenticator_asks_for_its_code(world):
    device = enrol(signed_in(world.operator), world.operator)
    client = Client(REMOTE_ADDR="192.0.2.44", HTTP_USER_AGENT="field tablet")
    first = client.post("/accounts/login/", {"username": "operator", "password": PASSWORD})
    assert first.status_code == 302 and first["Location"] == "/accounts/login/code/"
    assert client.get("/").status_code == 302  # not signed in yet
    wrong = client.post("/accounts/login/code/", {"code": "123456"})
    assert wrong.status_code == 400
    device.refresh_from_db()
    device.throttling_failure_count = 0
    device.save()
    right = client.post("/accounts/login/code/", {"code": code(device, ahead=1)})
    assert right.status_code == 302 and right["Location"] == "/"
    assert client.get("/").status_code == 200
    attempts = list(SignInAttempt.objects.filter(user=world.operator, ip="192.0.2.44"))
    assert [(a.succeeded, a.method) for a in attempts] == [
        (True, "password and one-time code"),
        (False, "one-time code"),
    ]
    page = client.get("/accounts/security/").content.decode()
    assert "password and one-time code" in page and "192.0.2.44" in page and "field tablet" in page


def test_a_token_for_a_user_with_an_authenticator_needs_its_code(world):
    device = enrol(signed_in(world.operator), world.operator)
    body = {"username": "operator", "password": PASSWORD}
    without = APIClient().post("/api/v1/token/", body, format="json")
    assert without.status_code == 403 and without.json()["code"] == "otp_required"
    with_code = APIClient().post(
        "/api/v1/token/", {**body, "otp": code(device, ahead=1)}, format="json"
    )
    assert with_code.status_code == 200 and with_code.json()["token"]


def test_failed_passwords_show_on_the_security_page(world):
    Client(REMOTE_ADDR="192.0.2.9").post(
        "/accounts/login/", {"username": "viewer", "password": "wrong"}
    )
    page = signed_in(world.viewer).get("/accounts/security/").content.decode()
    assert "failed" in page and "192.0.2.9" in page


def test_the_required_second_factor_cannot_be_turned_off(world):
    client = signed_in(world.operator)
    device = enrol(client, world.operator)
    require_second_factor(world.org)
    client.post("/accounts/security/two-factor/disable/", {"code": code(device, ahead=1)})
    assert TOTPDevice.objects.filter(user=world.operator, confirmed=True).exists()
    OrganisationSettings.objects.update(require_second_factor=False)
    client.post("/accounts/security/two-factor/disable/", {"code": code(device, ahead=1)})
    assert not TOTPDevice.objects.filter(user=world.operator).exists()


def test_an_admin_owing_the_required_second_factor_changes_no_member(world):
    require_second_factor(world.org)
    client = signed_in(world.owner)
    viewer = Membership.objects.get(user=world.viewer)
    assert client.get("/accounts/members/").status_code == 200
    refused = client.post(f"/accounts/members/{viewer.pk}/role/", {"role": "admin"})
    assert refused.status_code == 403
    viewer.refresh_from_db()
    assert viewer.role == "viewer"
    enrol(client, world.owner)
    assert client.post(f"/accounts/members/{viewer.pk}/role/", {"role": "admin"}).status_code == 302


def test_sign_ins_older_than_the_history_are_dropped(world, settings):
    settings.SIGN_IN_HISTORY_DAYS = 30
    old = SignInAttempt.objects.create(
        username="viewer",
        user=world.viewer,
        succeeded=False,
        method="password",
        at=timezone.now() - timedelta(days=31),
    )
    signed_in(world.viewer)
    assert not SignInAttempt.objects.filter(pk=old.pk).exists()
    assert SignInAttempt.objects.filter(user=world.viewer, succeeded=True).count() == 1

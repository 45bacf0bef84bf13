"""The Django admin under the portal's one sign-in policy, tried from the attacker's side:
the same LOGIN_RATE limit and code step as the portal, no entry for staff who owe their
organisation's second factor, and its use in the audit trail."""

from __future__ import annotations

import uuid

from django.core.cache import cache
from django.test import Client

from accounts.models import AuditEvent
from fleet.models import Drone

from .test_sign_in import PASSWORD, code, enrol, require_second_factor, signed_in


def address() -> str:
    """An address of its own per test: the counts outlive a test in the shared Redis."""
    return f"2001:db8::{uuid.uuid4().hex[:4]}:{uuid.uuid4().hex[:4]}"


def staff(user, superuser: bool = False):  # type: ignore[no-untyped-def]
    user.is_staff, user.is_superuser = True, superuser
    user.save()
    return user


def admin_login(client: Client, username: str, password: str, ip: str):  # type: ignore[no-untyped-def]
    body = {"username": username, "password": password, "next": "/admin/"}
    return client.post("/admin/login/", body, REMOTE_ADDR=ip)


def test_25_wrong_passwords_on_the_admin_login_end_in_429(world, settings):
    settings.LOGIN_RATE = "10/min"  # the production default
    # The per-username count outlives a test in the shared Redis like the address's:
    # another test's failed sign-in as "owner" within the minute would count here.
    cache.delete("login-failures:user:owner")
    staff(world.owner, superuser=True)
    guesser, client = address(), Client()
    codes = [admin_login(client, "owner", f"guess-{n}", guesser).status_code for n in range(25)]
    assert codes[:10] == [200] * 10 and codes[10:] == [429] * 15
    assert admin_login(client, "owner", PASSWORD, guesser).status_code == 429
    # Per username too: another address guessing the same account is refused as well.
    assert admin_login(Client(), "owner", PASSWORD, address()).status_code == 429
    assert Client().get("/admin/").status_code == 302


def test_the_admin_login_asks_a_staff_users_code(world):
    device = enrol(signed_in(world.owner), staff(world.owner, superuser=True))
    client = Client()
    first = admin_login(client, "owner", PASSWORD, address())
    assert first.status_code == 302 and first["Location"] == "/accounts/login/code/"
    assert client.get("/admin/").status_code == 302  # no admin on the password alone
    done = client.post("/accounts/login/code/", {"code": code(device, ahead=1)})
    assert done.status_code == 302 and done["Location"] == "/admin/"
    assert client.get("/admin/").status_code == 200


def test_staff_owing_the_required_second_factor_get_no_admin(world):
    require_second_factor(world.org)
    client = signed_in(staff(world.owner, superuser=True))
    assert client.get("/admin/").status_code == 302
    assert client.get("/admin/fleet/drone/").status_code == 302
    sent = client.get("/admin/login/")
    assert sent.status_code == 302 and sent["Location"] == "/accounts/security/"
    enrol(client, world.owner)  # this session gave its code
    assert client.get("/admin/fleet/drone/").status_code == 200


def test_a_session_with_an_authenticator_but_no_code_gets_no_admin(world):
    enrol(signed_in(world.owner), staff(world.owner, superuser=True))
    assert signed_in(world.owner).get("/admin/").status_code == 302


def test_opening_the_admin_and_its_changes_are_in_the_audit_trail(world):
    client = signed_in(staff(world.owner, superuser=True))
    assert client.get("/admin/").status_code == 200
    client.get("/admin/fleet/drone/")  # one entry per session, not per page
    opened = AuditEvent.objects.filter(action="admin.open", organisation=world.org)
    assert [(e.actor_name, e.target) for e in opened] == [("owner", "the Django admin")]
    deleted = client.post(f"/admin/fleet/drone/{world.drone.pk}/delete/", {"post": "yes"})
    assert deleted.status_code == 302 and not Drone.objects.filter(drone_id="ACME_1").exists()
    entry = AuditEvent.objects.get(action="admin.delete")
    assert entry.organisation == world.org and "ACME_1" in entry.target
    bulk = client.post(
        "/admin/fleet/drone/",
        {"action": "delete_selected", "_selected_action": [world.other_drone.pk], "post": "yes"},
    )
    assert bulk.status_code == 302 and not Drone.objects.filter(drone_id="GLOBEX_1").exists()
    action = AuditEvent.objects.get(action="admin.delete_selected")
    assert action.detail["selected"] == [str(world.other_drone.pk)]

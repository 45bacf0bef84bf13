"""The audit trail: every command, mission start/stop, envelope, member and token change,
with who, when, from where and the outcome; per organisation; append-only."""

from __future__ import annotations

import csv
import io
from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.utils import timezone

from accounts import tokens
from accounts.models import AuditEvent
from fleet.models import Membership
from missions.models import Event, Mission
from tests.fleet.conftest import client_for

PASSWORD = "correct horse battery staple"


def signed_in(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def rows(client: Client, query: str = "") -> list[dict]:
    response = client.get(f"/accounts/audit.csv{query}")
    assert response.status_code == 200
    assert response["Content-Type"] == "text/csv"
    text = b"".join(response.streaming_content).decode()
    return list(csv.DictReader(io.StringIO(text)))


@pytest.mark.django_db(transaction=True)
def test_the_audit_page_shows_a_command_with_its_author_and_address(world_tx, online):
    response = client_for(world_tx.operator).post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": "arm"},
        content_type="application/json",
        REMOTE_ADDR="198.51.100.7",
    )
    assert response.status_code == 200, response.content
    event = AuditEvent.objects.get(action="command.arm")
    assert (event.actor, event.outcome, event.target) == (world_tx.operator, "ok", "ACME_1")
    assert event.ip == "198.51.100.7" and event.organisation == world_tx.org
    page = signed_in(world_tx.owner).get("/accounts/audit/").content.decode()
    assert 'data-action="command.arm"' in page
    assert "operator" in page and "198.51.100.7" in page


def test_a_refused_command_is_recorded_as_refused_with_its_author(world):
    response = signed_in(world.viewer).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm"}, content_type="application/json"
    )
    assert response.status_code == 403
    event = AuditEvent.objects.get(kind="command")
    assert (event.actor_name, event.outcome, event.ip) == ("viewer", "refused", "127.0.0.1")
    assert "operators" in event.detail["error"]


def test_a_viewer_sees_their_own_trail_without_addresses_and_never_anothers(world):
    signed_in(world.viewer).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm"}, content_type="application/json"
    )
    signed_in(world.outsider).post(
        "/api/v1/drones/GLOBEX_1/commands/", {"command": "arm"}, content_type="application/json"
    )
    page = signed_in(world.viewer).get("/accounts/audit/").content.decode()
    assert "command.arm" in page and "ACME_1" in page
    assert "GLOBEX_1" not in page and "127.0.0.1" not in page
    assert [r["target"] for r in rows(signed_in(world.viewer))] == ["ACME_1"]
    assert [r["ip"] for r in rows(signed_in(world.viewer))] == [""]
    assert [r["target"] for r in rows(signed_in(world.outsider))] == ["GLOBEX_1"]
    # An address in the query does not reach another organisation's trail either.
    assert (
        "ACME_1"
        not in signed_in(world.outsider).get("/accounts/audit/?kind=command").content.decode()
    )
    assert Client().get("/accounts/audit/").status_code == 302


def test_member_and_token_changes_are_recorded(world):
    owner = signed_in(world.owner)
    owner.post("/accounts/members/invite/", {"email": "new@example.org", "role": "operator"})
    viewer = Membership.objects.get(user=world.viewer)
    owner.post(f"/accounts/members/{viewer.pk}/role/", {"role": "operator"})
    mine = Membership.objects.get(user=world.owner)
    owner.post(f"/accounts/members/{mine.pk}/remove/")  # the last admin: refused
    issued = tokens.issue(world.operator, name="cli", scope="read", organisation=world.org)
    tokens.revoke(issued.token)
    found = {(r["action"], r["target"], r["outcome"]) for r in rows(owner)}
    assert ("member.invite", "new@example.org", "ok") in found
    assert ("member.role", "viewer", "ok") in found
    assert ("member.remove", "owner", "refused") in found
    assert ("token.create", f"cli ({issued.token.prefix}…) of operator", "ok") in found
    assert ("token.revoke", f"cli ({issued.token.prefix}…) of operator", "ok") in found
    role = AuditEvent.objects.get(action="member.role")
    assert role.detail == {"before": "viewer", "after": "operator"} and role.actor == world.owner


def test_envelope_changes_and_mission_start_and_stop_are_recorded(world):
    body = {"max_height": 80, "max_distance": 500}
    response = signed_in(world.owner).put(
        "/api/v1/organisations/acme/envelope/", body, content_type="application/json"
    )
    assert response.status_code == 200, response.content
    envelope = AuditEvent.objects.get(kind="envelope")
    assert envelope.actor == world.owner and envelope.detail["envelope"]["max_height"] == 80

    mission = Mission.objects.create(organisation=world.org, name="North field")
    stopped = signed_in(world.operator).post(f"/api/v1/missions/{mission.pk}/stop/")
    assert stopped.status_code == 200, stopped.content
    stop = AuditEvent.objects.get(action="mission.stop")
    assert stop.actor == world.operator and "North field" in stop.target
    Event.objects.create(
        mission=mission, kind="decision", data={"decision": "start", "user": "operator"}
    )
    Event.objects.create(mission=mission, kind="decision", data={"decision": "dispatched"})
    assert AuditEvent.objects.filter(action="mission.start").count() == 1


def test_filters_by_actor_kind_and_date(world):
    for user in (world.owner, world.operator):
        tokens.issue(user, name="t", organisation=world.org)
    AuditEvent.objects.create(
        organisation=world.org,
        actor_name="operator",
        kind="command",
        action="command.arm",
        outcome="ok",
        at=timezone.now() - timedelta(days=3),
    )
    client = signed_in(world.owner)
    assert {r["actor"] for r in rows(client, "?actor=operator")} == {"operator"}
    assert {r["kind"] for r in rows(client, "?kind=command")} == {"command"}
    today = timezone.now().date().isoformat()
    assert {r["kind"] for r in rows(client, f"?from={today}")} == {"token"}
    assert len(rows(client, "?from=not-a-date")) == 3
    page = client.get("/accounts/audit/?actor=operator&kind=token").content.decode()
    assert page.count('data-action="token.create"') == 1


def test_a_csv_cell_cannot_become_a_spreadsheet_formula(world):
    tokens.issue(world.owner, name="=HYPERLINK(1)", organisation=world.org)
    assert rows(signed_in(world.owner))[0]["target"].startswith("'=HYPERLINK")


def test_the_trail_is_append_only_even_for_a_superuser(world):
    tokens.issue(world.owner, name="t", organisation=world.org)
    event = AuditEvent.objects.get()
    event.outcome = "failed"
    with pytest.raises(PermissionError):
        event.save()
    with pytest.raises(PermissionError):
        AuditEvent.objects.all().delete()
    with pytest.raises(PermissionError):
        AuditEvent.objects.update(outcome="failed")
    admin = User.objects.create_superuser("root", password=PASSWORD)
    client = signed_in(admin)
    assert client.get(f"/admin/accounts/auditevent/{event.pk}/change/").status_code == 200
    assert client.post(f"/admin/accounts/auditevent/{event.pk}/delete/").status_code == 403
    changed = client.post(f"/admin/accounts/auditevent/{event.pk}/change/", {"outcome": "x"})
    assert changed.status_code == 403
    assert AuditEvent.objects.get(pk=event.pk).outcome == "ok"
    # Opening the admin is itself in the trail (accounts/admin_site.py).
    assert AuditEvent.objects.filter(action="admin.open", actor_name="root").exists()
    # Deleting the account keeps its entries, under its name.
    world.owner.delete()
    assert AuditEvent.objects.get(pk=event.pk).actor_name == "owner"


@pytest.mark.django_db(transaction=True)
def test_under_the_asgi_server_the_caller_and_address_reach_the_trail(world_tx, live_asgi):
    import httpx

    key = tokens.issue(world_tx.operator, name="script").key
    response = httpx.post(
        f"{live_asgi.url}/api/v1/drones/ACME_1/commands/",
        json={"command": "arm"},
        headers={"Authorization": f"Token {key}"},
        timeout=30,
    )
    assert response.status_code == 409  # offline: refused by the command path
    event = AuditEvent.objects.get(kind="command")
    assert (event.actor, event.outcome, event.ip) == (world_tx.operator, "refused", "127.0.0.1")


def test_refused_envelope_changes_and_mission_actions_are_recorded_as_refused(world):
    owner = signed_in(world.owner)
    bad = owner.put(
        "/api/v1/organisations/acme/envelope/",
        {"max_height": -5},
        content_type="application/json",
    )
    assert bad.status_code == 400
    envelope = AuditEvent.objects.get(kind="envelope")
    assert (envelope.outcome, envelope.actor) == ("refused", world.owner)
    assert "max_height" in envelope.detail["reason"]

    mission = Mission.objects.create(organisation=world.org, name="Empty plan")
    operator = signed_in(world.operator)
    assert operator.post(f"/api/v1/missions/{mission.pk}/start/").status_code in (400, 409)
    assert operator.post(f"/api/v1/missions/{mission.pk}/stop/").status_code == 200
    assert operator.post(f"/api/v1/missions/{mission.pk}/stop/").status_code == 409
    found = [
        (e.action, e.outcome, e.actor_name)
        for e in AuditEvent.objects.filter(kind="mission").order_by("at", "id")
    ]
    assert found == [
        ("mission.start", "refused", "operator"),
        ("mission.stop", "ok", "operator"),
        ("mission.stop", "refused", "operator"),
    ]

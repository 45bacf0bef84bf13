"""The organisation settings page: its admins set the name, default home, alert
recipients and the second-factor rule; bad input changes nothing."""

from __future__ import annotations

from django.test import Client

from accounts.models import AuditEvent, OrganisationSettings
from fleet.models import Organisation

GOOD = {
    "name": "Acme Aerial",
    "default_home": "40.6303, -8.6575",
    "alert_recipients": "ops@example.org\nhttps://hooks.example.org/skyhive\nops@example.org",
    "require_second_factor": "on",
}


def signed_in(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def test_an_admin_changes_the_organisation_settings(world):
    client = signed_in(world.owner)
    page = client.get("/accounts/organisation/").content.decode()
    assert 'href="/organisation/envelope/"' in page
    assert client.post("/accounts/organisation/", GOOD).status_code == 302
    assert Organisation.objects.get(slug="acme").name == "Acme Aerial"
    stored = OrganisationSettings.objects.get(organisation=world.org)
    assert stored.default_home == [40.6303, -8.6575]
    assert stored.alert_recipients == ["ops@example.org", "https://hooks.example.org/skyhive"]
    assert stored.require_second_factor
    page = client.get("/accounts/organisation/").content.decode()
    assert "ops@example.org\nhttps://hooks.example.org/skyhive</textarea>" in page
    assert "40.6303, -8.6575" in page
    change = AuditEvent.objects.get(action="organisation.change")
    assert change.actor == world.owner
    assert change.detail["changed"]["name"] == "Acme Aerial"


def test_bad_settings_are_refused_by_field_and_change_nothing(world):
    client = signed_in(world.owner)
    for field, value, says in (
        ("name", "  ", "name"),
        ("default_home", "95, 10", "default home"),
        ("default_home", "north", "default home"),
        ("alert_recipients", "ops@example.org\nftp://x.example.org", "ftp://x.example.org"),
    ):
        response = client.post("/accounts/organisation/", {**GOOD, field: value})
        assert response.status_code == 400, field
        assert says in response.content.decode()
    assert Organisation.objects.get(slug="acme").name == "Acme"
    assert not OrganisationSettings.objects.filter(require_second_factor=True).exists()
    assert not AuditEvent.objects.exists()


def test_only_the_organisations_admins_reach_its_settings(world):
    for user in (world.operator, world.viewer):
        client = signed_in(user)
        assert client.get("/accounts/organisation/").status_code == 403
        assert client.post("/accounts/organisation/", GOOD).status_code == 403
    # An admin elsewhere changes only their own organisation.
    signed_in(world.outsider).post("/accounts/organisation/", GOOD)
    assert Organisation.objects.get(slug="acme").name == "Acme"
    assert Organisation.objects.get(slug="globex").name == "Acme Aerial"

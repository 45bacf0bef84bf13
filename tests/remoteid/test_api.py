"""The identity and airworthiness API: admins set numbers (400 naming the field, nothing
changed, for a wrong one), everyone else reads or gets 403/404; refusals of an arm."""

from __future__ import annotations

import pytest
from django.test import Client

from accounts.models import AuditEvent
from fleet.models import CommandLog, Drone, Organisation, Role
from tests import factories

pytestmark = pytest.mark.django_db

EU_NUMBER = "FIN87astrdge12k8-xyz"
SERIAL = "MFR1C123456789ABC"


def client_for(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def put(user, url: str, body: dict):  # type: ignore[no-untyped-def]
    return client_for(user).put(url, body, content_type="application/json")


@pytest.fixture
def acme() -> Organisation:
    org = factories.organisation("acme")
    org.require_remote_id = True
    org.save()
    return org


def test_an_admin_sets_the_operator_number_and_only_its_public_part_is_kept(acme):
    admin = factories.person(acme, Role.ADMIN)
    response = put(admin, "/api/v1/organisations/acme/remote-id/", {"operator_id": EU_NUMBER})
    assert response.status_code == 200, response.content
    assert response.json()["operator_id"] == "FIN87astrdge12k8"
    acme.refresh_from_db()
    assert acme.operator_id == "FIN87astrdge12k8"
    event = AuditEvent.objects.get(action="remote_id.operator")
    assert event.actor == admin and event.detail == {"changed": {"operator_id": "FIN87astrdge12k8"}}


def test_a_wrong_checksum_answers_400_naming_the_field_and_changes_nothing(acme):
    acme.operator_id = "FA3ABCDE12"
    acme.save()
    admin = factories.person(acme, Role.ADMIN)
    response = put(
        admin, "/api/v1/organisations/acme/remote-id/", {"operator_id": "FIN87astrdge12k9-xyz"}
    )
    assert response.status_code == 400
    body = response.json()
    assert list(body["fields"]) == ["operator_id"]
    assert "checksum" in body["error"]
    acme.refresh_from_db()
    assert acme.operator_id == "FA3ABCDE12"
    assert not AuditEvent.objects.filter(action="remote_id.operator").exists()


def test_a_bad_serial_number_answers_400_naming_the_field(acme):
    factories.drone(acme, "ACME_1")
    admin = factories.person(acme, Role.ADMIN)
    response = put(admin, "/api/v1/drones/ACME_1/identity/", {"serial_number": "MFR1C12345"})
    assert response.status_code == 400
    assert list(response.json()["fields"]) == ["serial_number"]
    assert Drone.objects.get(drone_id="ACME_1").serial_number == ""


def test_unknown_fields_and_non_booleans_are_refused_by_name(acme):
    factories.drone(acme, "ACME_1")
    admin = factories.person(acme, Role.ADMIN)
    url = "/api/v1/drones/ACME_1/identity/"
    assert list(put(admin, url, {"serial": SERIAL}).json()["fields"]) == ["serial"]
    refused = put(admin, url, {"remote_id_external": "yes"})
    assert refused.status_code == 400
    assert list(refused.json()["fields"]) == ["remote_id_external"]


def test_two_drones_cannot_share_a_serial_number(acme):
    factories.drone(acme, "ACME_1", serial_number=SERIAL)
    factories.drone(acme, "ACME_2")
    admin = factories.person(acme, Role.ADMIN)
    response = put(admin, "/api/v1/drones/ACME_2/identity/", {"serial_number": SERIAL})
    assert response.status_code == 400
    assert list(response.json()["fields"]) == ["serial_number"]


def test_operators_read_but_may_not_set_identities(acme):
    factories.drone(acme, "ACME_1")
    operator = factories.person(acme, Role.OPERATOR)
    client = client_for(operator)
    assert client.get("/api/v1/drones/ACME_1/identity/").status_code == 200
    assert client.get("/api/v1/organisations/acme/remote-id/").status_code == 200
    assert (
        put(operator, "/api/v1/drones/ACME_1/identity/", {"serial_number": SERIAL}).status_code
        == 403
    )
    assert (
        put(
            operator, "/api/v1/organisations/acme/remote-id/", {"operator_id": EU_NUMBER}
        ).status_code
        == 403
    )
    assert Drone.objects.get(drone_id="ACME_1").serial_number == ""


def test_another_organisation_sees_nothing(acme):
    factories.drone(acme, "ACME_1")
    other = factories.organisation("other")
    stranger = factories.person(other, Role.ADMIN)
    client = client_for(stranger)
    assert client.get("/api/v1/drones/ACME_1/identity/").status_code == 404
    assert client.get("/api/v1/drones/ACME_1/airworthiness/").status_code == 404
    assert client.get("/api/v1/organisations/acme/remote-id/").status_code == 404
    assert (
        put(stranger, "/api/v1/drones/ACME_1/identity/", {"serial_number": SERIAL}).status_code
        == 404
    )


def test_airworthiness_names_every_missing_piece_then_clears(acme):
    factories.drone(acme, "ACME_1")
    admin = factories.person(acme, Role.ADMIN)
    url = "/api/v1/drones/ACME_1/airworthiness/"
    verdict = client_for(admin).get(url).json()
    assert verdict["airworthy"] is False
    assert [r.split(":")[0].split(" ")[0:2] for r in verdict["reasons"]] == [
        ["no", "serial"],
        ["the", "organisation"],
        ["no", "Remote"],
    ]
    put(admin, "/api/v1/organisations/acme/remote-id/", {"operator_id": EU_NUMBER})
    put(
        admin,
        "/api/v1/drones/ACME_1/identity/",
        {"serial_number": SERIAL, "remote_id_external": True},
    )
    assert client_for(admin).get(url).json() == {"airworthy": True, "reasons": []}
    declared = AuditEvent.objects.get(action="remote_id.drone")
    assert declared.actor == admin and declared.target == "ACME_1"
    assert declared.detail["changed"] == {"serial_number": SERIAL, "remote_id_external": True}


def test_a_failing_module_keeps_a_drone_down_even_where_remote_id_is_not_required(acme):
    acme.require_remote_id = False
    acme.save()
    factories.drone(
        acme,
        "ACME_1",
        fc={"protocol": "mavlink", "remote_id": {"ok": False, "error": "no operator ID"}},
    )
    viewer = factories.person(acme, Role.VIEWER)
    verdict = client_for(viewer).get("/api/v1/drones/ACME_1/airworthiness/").json()
    assert verdict == {"airworthy": False, "reasons": ["Remote ID failing: no operator ID"]}


def test_arming_a_drone_that_is_not_airworthy_answers_409_and_sends_nothing(acme):
    factories.drone(acme, "ACME_1", online=True)
    operator = factories.person(acme, Role.OPERATOR)
    response = client_for(operator).post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": "arm", "params": {}},
        content_type="application/json",
    )
    assert response.status_code == 409
    body = response.json()
    assert body["code"] == "not_airworthy"
    assert "no serial number" in body["error"]
    assert CommandLog.objects.get().outcome == CommandLog.Outcome.REJECTED


def test_an_admin_declares_the_aircraft_by_name_and_the_audit_trail_names_it(acme):
    factories.drone(acme, "ACME_1")
    admin = factories.person(acme, Role.ADMIN)
    url = "/api/v1/drones/ACME_1/identity/"
    before = client_for(admin).get(url).json()
    assert (before["ua_type"], before["eu_category"], before["eu_class"]) == (
        "helicopter_or_multirotor",
        "undeclared",
        "undeclared",
    )
    body = {"ua_type": "hybrid_lift", "eu_category": "specific", "eu_class": "C5"}
    response = put(admin, url, body)
    assert response.status_code == 200, response.content
    assert {k: response.json()[k] for k in body} == body
    drone = Drone.objects.get(drone_id="ACME_1")
    assert (drone.ua_type, drone.eu_category, drone.eu_class) == (4, 2, 6)
    audit = AuditEvent.objects.get(action="remote_id.drone")
    assert "C5" in str(audit.__dict__) and "hybrid_lift" in str(audit.__dict__)


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"ua_type": "drone"}, "ua_type"),
        ({"ua_type": 2}, "ua_type"),
        ({"eu_category": "OPEN"}, "eu_category"),
        ({"eu_class": "C7"}, "eu_class"),
        # C5 and C6 are for the specific category's standard scenarios.
        ({"eu_category": "open", "eu_class": "C6"}, "eu_class"),
        ({"eu_class": "C5"}, "eu_class"),
        ({"eu_category": "certified", "eu_class": "C2"}, "eu_class"),
    ],
)
def test_a_declaration_that_is_not_one_or_does_not_fit_is_refused_naming_it(acme, body, field):
    factories.drone(acme, "ACME_1")
    admin = factories.person(acme, Role.ADMIN)
    response = put(admin, "/api/v1/drones/ACME_1/identity/", body)
    assert response.status_code == 400
    assert list(response.json()["fields"]) == [field]
    drone = Drone.objects.get(drone_id="ACME_1")
    assert (drone.ua_type, drone.eu_category, drone.eu_class) == (2, 0, 0)


def test_the_declaration_goes_to_the_drone_with_its_identity(acme):
    from fleet.identity import identity_for

    drone = factories.drone(acme, "ACME_1", serial_number=SERIAL)
    assert identity_for(drone).to_dict().keys() == {
        "serial_number",
        "operator_id",
        "ua_type",
        "description",
        "operator_location",
    }  # undeclared: nothing new on the wire
    admin = factories.person(acme, Role.ADMIN)
    body = {"ua_type": "aeroplane", "eu_category": "open", "eu_class": "C1"}
    assert put(admin, "/api/v1/drones/ACME_1/identity/", body).status_code == 200
    sent = identity_for(Drone.objects.get(drone_id="ACME_1")).to_dict()
    assert (sent["ua_type"], sent["eu_category"], sent["eu_class"]) == (1, 1, 2)

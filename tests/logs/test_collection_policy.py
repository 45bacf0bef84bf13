"""A drone's log collection mode on the ground: set by operators and admins on the drone
page or through the API, recorded in the audit trail and queued for the drone with its
envelope; viewers are refused (403), another organisation's drone is not found (404), a
bad value is refused naming the field and changes nothing."""

from __future__ import annotations

import json

import pytest
from django.test import Client

from accounts.models import AuditEvent
from fleet.models import Drone
from onboard import protocol
from workers import outbox

pytestmark = pytest.mark.django_db

API = "/api/v1/logs/collection/{}/"
PAGE = "/logs/collection/{}/"


def client_for(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def put(user, drone_id: str, body: object):  # type: ignore[no-untyped-def]
    return client_for(user).put(API.format(drone_id), body, content_type="application/json")


def envelope_messages(drone_id: str) -> list[dict]:
    """The envelope messages queued for the drone, parsed as the drone parses them."""
    topic = protocol.topic(drone_id, "envelope", "in")
    raw = outbox.sync_redis().lrange(outbox.outbox_key(), 0, -1)
    items = [json.loads(item) for item in raw]
    return [item["payload"] for item in items if item["topic"] == topic]


def mode_of(drone_id: str) -> str:
    return Drone.objects.get(drone_id=drone_id).log_collection


def test_a_new_drone_collects_always_and_members_read_it(world):
    response = client_for(world.viewer).get(API.format("ACME_1"))
    assert response.status_code == 200
    assert response.json() == {"drone_id": "ACME_1", "log_collection": "always"}
    drone = client_for(world.viewer).get("/api/v1/drones/ACME_1/").json()
    assert drone["log_collection"] == "always"


def test_an_operator_turns_it_off_audited_and_sent_with_the_envelope(
    world, django_capture_on_commit_callbacks
):
    with django_capture_on_commit_callbacks(execute=True):
        response = put(world.operator, "ACME_1", {"log_collection": "off"})
    assert response.status_code == 200, response.content
    assert response.json()["log_collection"] == "off"
    assert mode_of("ACME_1") == "off"
    event = AuditEvent.objects.get(action="drone.log_collection")
    assert event.actor == world.operator and event.target == "ACME_1"
    assert event.detail == {"changed": {"log_collection": "off"}}
    sent = [protocol.parse_envelope_update(m) for m in envelope_messages("ACME_1")]
    assert sent and sent[-1].log_collection == "off"


def test_setting_the_mode_it_has_changes_nothing_and_records_nothing(world):
    response = put(world.owner, "ACME_1", {"log_collection": "always"})
    assert response.status_code == 200
    assert not AuditEvent.objects.filter(action="drone.log_collection").exists()


def test_a_viewer_is_refused_and_nothing_changes(world):
    response = put(world.viewer, "ACME_1", {"log_collection": "off"})
    assert response.status_code == 403
    page = client_for(world.viewer).post(PAGE.format("ACME_1"), {"log_collection": "off"})
    assert page.status_code == 403
    assert mode_of("ACME_1") == "always"


def test_another_organisations_drone_is_not_found(world):
    assert put(world.operator, "GLOBEX_1", {"log_collection": "off"}).status_code == 404
    assert client_for(world.operator).get(API.format("GLOBEX_1")).status_code == 404
    page = client_for(world.operator).post(PAGE.format("GLOBEX_1"), {"log_collection": "off"})
    assert page.status_code == 404
    assert mode_of("GLOBEX_1") == "always"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"log_collection": "sometimes"}, "log_collection"),
        ({"log_collection": None}, "log_collection"),
        ({"log_collection": ["off"]}, "log_collection"),
        ({}, "log_collection"),
        ({"log_collection": "off", "collect": "off"}, "collect"),
        (["off"], "non_field_errors"),
    ],
)
def test_a_bad_value_is_refused_naming_the_field_and_changes_nothing(world, body, field):
    response = put(world.operator, "ACME_1", body)
    assert response.status_code == 400, response.content
    assert list(response.json()["fields"]) == [field]
    assert mode_of("ACME_1") == "always"
    assert not AuditEvent.objects.filter(action="drone.log_collection").exists()


def test_the_drone_page_shows_the_form_to_operators_and_sets_the_mode(world):
    client = client_for(world.operator)
    page = client.get("/drones/ACME_1/")
    assert b'id="log-collection-form"' in page.content
    response = client.post(PAGE.format("ACME_1"), {"log_collection": "ground_links"})
    assert response.status_code == 302 and response["Location"] == "/drones/ACME_1/"
    assert mode_of("ACME_1") == "ground_links"
    assert AuditEvent.objects.get(action="drone.log_collection").actor == world.operator
    bad = client.post(PAGE.format("ACME_1"), {"log_collection": "never"})
    assert bad.status_code == 400 and bad.content.startswith(b"log_collection:")
    assert mode_of("ACME_1") == "ground_links"


def test_a_viewer_sees_the_mode_without_the_form(world):
    page = client_for(world.viewer).get("/drones/ACME_1/")
    assert b'data-log-collection="always"' in page.content
    assert b'id="log-collection-form"' not in page.content


def test_the_api_schema_lists_the_resource_and_its_modes(world):
    schema = client_for(world.viewer).get("/api/schema/?format=json").json()
    operation = schema["paths"]["/api/v1/logs/collection/{drone_id}/"]
    assert {"get", "put"} <= set(operation)
    components = schema["components"]["schemas"]

    def resolve(node: dict) -> dict:
        while "$ref" in node or "allOf" in node:
            node = node["allOf"][0] if "allOf" in node else node
            if "$ref" in node:
                node = components[node["$ref"].split("/")[-1]]
        return node

    body = operation["put"]["requestBody"]["content"]["application/json"]["schema"]
    mode = resolve(resolve(body)["properties"]["log_collection"])
    assert set(mode["enum"]) == {"always", "ground_links", "off"}

"""The operation's contracts as the API schema publishes them: the flights list with its
filters and fields, the batteries list, a drone's airworthiness, and the 409 codes a
refused arm or mission start answers."""

from __future__ import annotations

import pytest
from rest_framework.test import APIClient

pytestmark = pytest.mark.django_db

FLIGHT_FIELDS = {
    "started_at", "ended_at", "duration_s", "distance_m", "max_height_m", "max_distance_m",
    "battery_start", "battery_end", "energy_wh", "battery", "pilot", "mission", "events",
}  # fmt: skip


@pytest.fixture
def schema(world) -> dict:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(world.viewer)
    return client.get("/api/schema/?format=json").json()


def _listed(schema: dict, path: str) -> tuple[set[str], dict]:
    """The query parameters of a paginated list, and its item's properties."""
    operation = schema["paths"][path]["get"]
    page = operation["responses"]["200"]["content"]["application/json"]["schema"]["$ref"]
    components = schema["components"]["schemas"]
    item = components[page.rsplit("/", 1)[1]]["properties"]["results"]["items"]["$ref"]
    names = {p["name"] for p in operation.get("parameters", [])}
    return names, components[item.rsplit("/", 1)[1]]["properties"]


def test_the_flights_list_publishes_its_filters_and_fields(schema):
    filters, fields = _listed(schema, "/api/v1/flights/")
    assert {"drone", "pilot", "mission", "since", "until"} <= filters
    assert FLIGHT_FIELDS <= fields.keys()


def test_the_batteries_list_publishes_each_packs_figures(schema):
    _, fields = _listed(schema, "/api/v1/batteries/")
    assert {"serial", "cycles", "energy_wh", "age_days", "health", "retired"} <= fields.keys()


def test_airworthiness_publishes_the_verdict_and_its_reasons(schema):
    answer = schema["paths"]["/api/v1/drones/{drone_id}/airworthiness/"]["get"]["responses"]
    ref = answer["200"]["content"]["application/json"]["schema"]["$ref"]
    body = schema["components"]["schemas"][ref.rsplit("/", 1)[1]]
    assert body["properties"]["airworthy"]["type"] == "boolean"
    assert body["properties"]["reasons"]["items"]["type"] == "string"
    assert set(body["required"]) == {"airworthy", "reasons"}


@pytest.mark.parametrize(
    "path", ["/api/v1/drones/{drone_id}/commands/", "/api/v1/missions/{id}/start/"]
)
def test_refusals_publish_not_airworthy_and_checklist_required(schema, path):
    refused = schema["paths"][path]["post"]["responses"]["409"]["description"]
    assert "not_airworthy" in refused and "checklist_required" in refused


def test_the_airworthiness_answer_matches_its_schema(world):
    client = APIClient()
    client.force_authenticate(world.viewer)
    answer = client.get(f"/api/v1/drones/{world.drone.drone_id}/airworthiness/").json()
    assert answer == {"airworthy": True, "reasons": []}
    other = client.get(f"/api/v1/drones/{world.other_drone.drone_id}/airworthiness/")
    assert other.status_code == 404

"""A refusal with 409 `not_airworthy` lists its reasons one by one in `reasons`, the same
strings the airworthiness endpoint gives, wherever it is answered: the commands endpoint,
/control and a mission's start; the API schema documents the member."""

from __future__ import annotations

import pytest
from rest_framework.test import APIClient

from fleet.models import CommandLog
from tests.missions.conftest import online_drone, outbox, point_at  # noqa: F401 (fixture)

from .conftest import client_for

pytestmark = pytest.mark.django_db

FAILING = {"protocol": "mavlink", "remote_id": {"ok": False, "error": "no operator ID"}}


def _api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def _unfit(world):  # type: ignore[no-untyped-def]
    """An online drone with two reasons to stay on the ground: Remote ID is required and
    it has no serial number, and its module reports a failure."""
    world.org.require_remote_id = True
    world.org.operator_id = "FIN87astrdge12k8"
    world.org.save()
    drone = online_drone(world.org, "ACME_1")
    drone.fc = FAILING
    drone.save()
    return drone


def _listed_reasons(world) -> list[str]:  # type: ignore[no-untyped-def]
    verdict = _api(world.viewer).get("/api/v1/drones/ACME_1/airworthiness/").json()
    assert verdict["airworthy"] is False and len(verdict["reasons"]) == 2, verdict
    return verdict["reasons"]


def test_a_refused_arm_lists_the_reasons(world):
    _unfit(world)
    reasons = _listed_reasons(world)
    response = _api(world.operator).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm", "params": {}}, format="json"
    )
    assert response.status_code == 409, response.content
    body = response.json()
    assert body["code"] == "not_airworthy" and body["fields"] == {}
    assert body["reasons"] == reasons
    assert all(reason in body["error"] for reason in reasons)
    assert CommandLog.objects.get().outcome == CommandLog.Outcome.REJECTED


def test_other_refusals_carry_no_reasons(world):
    drone = _unfit(world)
    drone.online = False
    drone.save()
    response = _api(world.operator).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm", "params": {}}, format="json"
    )
    assert response.status_code == 409 and "offline" in response.json()["error"]
    assert "reasons" not in response.json()


def test_control_lists_the_reasons(world_tx):
    # The threaded client answers from another thread: committed data (world_tx).
    _unfit(world_tx)
    reasons = _listed_reasons(world_tx)
    response = client_for(world_tx.operator).post(
        "/control", {"command": "arm", "droneID": "ACME_1"}
    )
    assert response.status_code == 409, response.content
    body = response.json()
    assert body["ok"] is False and body["code"] == "not_airworthy"
    assert body["reasons"] == reasons


def test_a_refused_mission_start_lists_the_reasons(world, outbox):  # noqa: F811
    _unfit(world)
    reasons = _listed_reasons(world)
    client = _api(world.operator)
    lat, lon = point_at(20, 0)
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10}}]
    steps += [{"command": "navigate", "params": {"lat": lat, "lon": lon}}, {"command": "land"}]
    body = {"name": "survey", "steps": steps}
    created = client.post("/api/v1/missions/", body, format="json")
    assert created.status_code == 201, created.content
    response = client.post(
        f"/api/v1/missions/{created.json()['id']}/start/", {"drone": "ACME_1"}, format="json"
    )
    assert response.status_code == 409, response.content
    answer = response.json()
    assert answer["code"] == "not_airworthy" and answer["reasons"] == reasons
    assert outbox.items() == []


@pytest.mark.parametrize(
    ("path", "method"),
    [
        ("/api/v1/drones/{drone_id}/commands/", "post"),
        ("/api/v1/missions/{id}/start/", "post"),
        ("/control", "post"),
    ],
)
def test_the_schema_documents_the_reasons(world, path, method):
    schema = _api(world.viewer).get("/api/schema/?format=json").json()
    conflict = schema["paths"][path][method]["responses"]["409"]
    assert "reasons" in conflict["description"]
    ref = conflict["content"]["application/json"]["schema"]["$ref"]
    body = schema["components"]["schemas"][ref.rsplit("/", 1)[1]]
    assert body["properties"]["reasons"]["items"]["type"] == "string"
    assert "reasons" not in body.get("required", [])

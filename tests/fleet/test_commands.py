"""The Drone Manager: /control and the commands API, through a real gateway and broker."""

from __future__ import annotations

import pytest

from fleet import credentials
from fleet.models import CommandLog, Drone

from .conftest import Responder, client_for

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def online(world_tx, broker, gateway):  # type: ignore[no-untyped-def]
    """ACME_1 online, provisioned, answering commands."""
    creds = credentials.provision("ACME_1")
    Drone.objects.filter(drone_id="ACME_1").update(online=True)
    responder = Responder(
        f"mqtt://ACME_1:{creds.password}@127.0.0.1:{broker.port}", "ACME_1", refuse=("takepic",)
    )
    yield responder
    responder.stop()


def test_an_operator_arms_a_drone_through_control_and_gets_its_reply(world_tx, online):
    response = client_for(world_tx.operator).post(
        "/control", {"command": "arm", "droneID": "ACME_1"}
    )
    assert response.status_code == 200, response.content
    body = response.json()
    assert body["ok"] is True and body["result"] == {"echo": {}}
    assert len(body["request_id"]) == 32
    assert online.requests[0]["request_id"] == body["request_id"]
    entry = CommandLog.objects.get(request_id=body["request_id"])
    assert (entry.command, entry.outcome, entry.user) == ("arm", "ok", world_tx.operator)


def test_navigate_sends_the_control_parameters_normalised(world_tx, online):
    response = client_for(world_tx.operator).post(
        "/control?command=navigate&droneID=ACME_1", {"lat": "40.1", "lon": "-8.5"}
    )
    assert response.status_code == 200, response.content
    assert online.requests[-1]["params"] == {"lat": 40.1, "lon": -8.5, "altitude_delta": 0.0}


def test_a_drone_refusal_answers_409_with_its_reason_and_is_logged(world_tx, online):
    response = client_for(world_tx.operator).post(
        "/control", {"command": "takepic", "droneID": "ACME_1"}
    )
    assert response.status_code == 409
    assert response.json()["error"] == "refused by the test drone"
    assert CommandLog.objects.get(command="takepic").outcome == "failed"


@pytest.mark.parametrize(
    ("who", "data", "status", "error_part"),
    [
        ("viewer", {"command": "arm", "droneID": "ACME_1"}, 403, "operators"),
        ("operator", {"command": "arm", "droneID": "GLOBEX_1"}, 404, "GLOBEX_1"),
        ("operator", {"command": "arm", "droneID": "NOPE"}, 404, "NOPE"),
        ("operator", {"command": "arm"}, 400, "droneID"),
        ("operator", {"droneID": "ACME_1"}, 400, "command"),
        ("operator", {"command": "fly", "droneID": "ACME_1"}, 400, "command"),
        ("operator", {"command": "discover"}, 405, "GET"),
        ("operator", {"command": "changeN", "droneID": "ACME_1"}, 400, "value"),
        ("operator", {"command": "changeN", "droneID": "ACME_1", "value": "x"}, 400, "value"),
        (
            "operator",
            {"command": "navigate", "droneID": "ACME_1", "lat": "91", "lon": "0"},
            400,
            "lat",
        ),
        (
            "operator",
            {"command": "navigate", "droneID": "ACME_1", "lat": "0", "lon": "-181"},
            400,
            "lon",
        ),
    ],
)
def test_bad_commands_are_refused_before_anything_is_sent(
    world_tx, online, who, data, status, error_part
):
    response = client_for(getattr(world_tx, who)).post("/control", data)
    assert response.status_code == status, response.content
    assert response.json()["ok"] is False
    assert error_part in response.json()["error"]
    assert online.requests == []


def test_an_offline_drone_answers_409(world_tx, online):
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    response = client_for(world_tx.operator).post(
        "/control", {"command": "arm", "droneID": "ACME_1"}
    )
    assert response.status_code == 409 and "offline" in response.json()["error"]
    assert CommandLog.objects.get(command="arm").outcome == "rejected"


def test_disarm_while_airborne_needs_force(world_tx, online):
    Drone.objects.filter(drone_id="ACME_1").update(airborne=True)
    client = client_for(world_tx.operator)
    refused = client.post("/control", {"command": "disarm", "droneID": "ACME_1"})
    assert refused.status_code == 409 and "airborne" in refused.json()["error"]
    assert online.requests == []
    forced = client.post("/control", {"command": "disarm", "droneID": "ACME_1", "force": "true"})
    assert forced.status_code == 200
    assert online.requests[0]["params"] == {"force": True}


def test_no_reply_in_time_answers_504(world_tx, broker, gateway, settings):
    settings.COMMAND_TIMEOUT_S = 0.5
    Drone.objects.filter(drone_id="ACME_1").update(online=True)
    response = client_for(world_tx.operator).post(
        "/control", {"command": "arm", "droneID": "ACME_1"}
    )
    assert response.status_code == 504
    assert CommandLog.objects.get(command="arm").outcome == "timeout"


def test_discover_lists_only_the_users_drones_with_specs(world_tx):
    Drone.objects.filter(drone_id="ACME_1").update(specs={"TYPE": "QUAD"})
    response = client_for(world_tx.viewer).get("/control", {"command": "discover"})
    assert response.status_code == 200
    drones = response.json()["result"]["drones"]
    assert [d["drone_id"] for d in drones] == ["ACME_1"]
    assert drones[0]["specs"] == {"TYPE": "QUAD"} and drones[0]["online"] is False


def test_getgear_answers_from_the_drone_identifier(world_tx):
    Drone.objects.filter(drone_id="ACME_1").update(sensors={"GAS": {"CO2": "SCD30"}})
    response = client_for(world_tx.viewer).get("/control?command=getgear&droneID=ACME_1")
    assert response.json()["result"]["sensors"] == {"GAS": {"CO2": "SCD30"}}


def test_control_needs_a_login(world_tx):
    response = client_for().get("/control", {"command": "discover"})
    assert response.status_code in (401, 403)
    assert response.json()["ok"] is False


def test_a_token_client_commands_through_the_resource_api(world_tx, online):
    from rest_framework.authtoken.models import Token

    token = Token.objects.create(user=world_tx.operator)
    client = client_for()
    client.defaults["HTTP_AUTHORIZATION"] = f"Token {token.key}"
    response = client.post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": "changeE", "params": {"value": -3}},
        content_type="application/json",
    )
    assert response.status_code == 200, response.content
    body = response.json()
    assert body["ok"] is True and body["result"] == {"echo": {"value": -3.0}}
    bad = client.post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": "navigate", "params": {"lat": 1}},
        content_type="application/json",
    )
    assert bad.status_code == 400 and "lon" in bad.json()["fields"]
    viewer = client_for(world_tx.viewer).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm"}, content_type="application/json"
    )
    assert viewer.status_code == 403


def test_connection_history_and_gear_are_resources(world_tx):
    client = client_for(world_tx.viewer)
    assert client.get("/api/v1/drones/ACME_1/gear/").json()["drone_id"] == "ACME_1"
    assert client.get("/api/v1/drones/ACME_1/connections/").json()["results"] == []
    assert client.get("/api/v1/drones/GLOBEX_1/gear/").status_code == 404

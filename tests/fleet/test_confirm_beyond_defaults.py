"""Moves beyond the envelope's defaults, and legs across the fence, on the ground.

Rule: an organisation may raise its limits above the defaults (120 m high, 1000 m from
home); a command going beyond them is then sent only with `confirm_beyond_defaults`, else
409 `confirmation_required` naming the default limit, and nothing is sent. The leg from
the drone's current target to the new one must keep to the geofence as its end does.

The outbox is first in, first out: when the one request a drone receives is the confirmed
one sent after a refusal, the refused one was never queued.
"""

from __future__ import annotations

import pytest

from fleet.models import CommandLog, Drone, Organisation
from onboard import envelope as env
from runtime.processes import wait_for

from .conftest import client_for
from .test_envelope import HOME, command, flying  # noqa: F401 (fixture)

pytestmark = pytest.mark.django_db(transaction=True)

RAISED = {"max_height": 300.0, "max_distance": 3000.0}


def raise_limits(extra: dict | None = None) -> None:
    Organisation.objects.filter(slug="acme").update(envelope={**RAISED, **(extra or {})})


def confirmed(user, name: str, **params: object):  # type: ignore[no-untyped-def]
    return client_for(user).post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": name, "params": params, "confirm_beyond_defaults": True},
        content_type="application/json",
    )


def only_received(responder, name: str) -> None:  # type: ignore[no-untyped-def]
    assert wait_for(lambda: responder.requests, timeout=10)
    assert [r["command"] for r in responder.requests] == [name]


@pytest.mark.parametrize(
    ("name", "params", "words"),
    [
        ("altitude", {"value": 150}, "default maximum height of 120 m"),
        ("changeN", {"value": 1500}, "default maximum distance of 1000 m"),
        ("takeoff", {"altitude": 200}, "default maximum height of 120 m"),
    ],
)
def test_beyond_the_defaults_needs_a_confirmation(world_tx, flying, name, params, words):  # noqa: F811
    if name == "takeoff":
        Drone.objects.filter(drone_id="ACME_1").update(airborne=False, alt=0.0, nav_target=None)
    raise_limits()
    refused = command(world_tx.operator, name, **params)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "confirmation_required"
    assert words in refused.json()["error"]
    assert CommandLog.objects.get().outcome == "rejected"

    sent = confirmed(world_tx.operator, name, **params)
    assert sent.status_code == 200, sent.content
    assert sent.json()["ok"] is True
    only_received(flying, name)


def test_within_the_defaults_no_confirmation_is_asked(world_tx, flying):  # noqa: F811
    raise_limits()
    assert command(world_tx.operator, "altitude", value=100).status_code == 200
    only_received(flying, "altitude")


def test_a_confirmation_never_lets_a_move_leave_the_envelope(world_tx, flying):  # noqa: F811
    raise_limits()
    refused = confirmed(world_tx.operator, "altitude", value=400)
    assert refused.status_code == 409 and refused.json()["code"] == "outside_envelope"
    assert "maximum height of 300 m" in refused.json()["error"]
    assert confirmed(world_tx.operator, "land").status_code == 200
    only_received(flying, "land")


def test_control_takes_the_confirmation_as_a_form_field(world_tx, flying):  # noqa: F811
    raise_limits()
    client = client_for(world_tx.operator)
    form = {"command": "altitude", "droneID": "ACME_1", "value": "150"}
    refused = client.post("/control", form)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "confirmation_required"
    assert "default maximum height" in refused.json()["error"]
    sent = client.post("/control", {**form, "confirm_beyond_defaults": "true"})
    assert sent.status_code == 200, sent.content
    only_received(flying, "altitude")


def test_the_openapi_schema_documents_the_confirmation(world_tx):
    schema = client_for(world_tx.viewer).get("/api/schema/?format=json").json()
    body = schema["components"]["schemas"]["CommandRequestRequest"]["properties"]
    assert body["confirm_beyond_defaults"]["type"] == "boolean"
    operation = schema["paths"]["/api/v1/drones/{drone_id}/commands/"]["post"]
    assert "confirmation_required" in operation["responses"]["409"]["description"]


def exclusion_circle(north: float, east: float, radius: float) -> dict:
    center = list(env.ned_to_latlon(north, east, HOME))
    circle = {"inclusion": False, "circle": {"center": center, "radius": radius}, "version": 1}
    return {"geoFence": {"version": 2, "polygons": [], "circles": [circle]}}


def test_a_leg_across_an_exclusion_zone_is_refused_one_beside_it_is_sent(world_tx, flying):  # noqa: F811
    Organisation.objects.filter(slug="acme").update(envelope=exclusion_circle(0, 60, 20))
    # 120 m east ends outside the zone, but the straight leg from the target crosses it.
    refused = command(world_tx.operator, "changeE", value=120)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "outside_envelope"
    assert "leg" in refused.json()["error"] and "exclusion circle 0" in refused.json()["error"]
    # From a target 30 m north, reached, the leg passes 30 m from the zone's centre (on
    # its way there, the leg from where it is would still cross the zone).
    lat, lon = env.ned_to_latlon(30.0, 0.0, HOME)
    Drone.objects.filter(drone_id="ACME_1").update(nav_target=[30.0, 0.0, -10.0], lat=lat, lon=lon)
    assert command(world_tx.operator, "changeE", value=120).status_code == 200
    only_received(flying, "changeE")

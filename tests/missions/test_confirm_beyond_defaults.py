"""Missions beyond the envelope's defaults, and mission legs across the fence.

Rule: with the organisation's limits raised above the defaults (120 m high, 1000 m from
home), a mission with a step beyond them is created, imported, started or called (panic)
only with `confirm_beyond_defaults`; else 409 `confirmation_required` naming the step and
the default limit, and nothing is stored or sent. A step whose straight leg crosses an
exclusion zone is refused as `outside_envelope`, naming the step.
"""

from __future__ import annotations

import pytest

from fleet.models import Organisation
from missions.models import Assignment, Mission

from .conftest import online_drone, point_at
from .test_envelope import body, client_for, qgc_mission, sent  # noqa: F401 (fixture)

RAISED = {"max_height": 300.0, "max_distance": 3000.0}
CONFIRM = {"confirm_beyond_defaults": True}


@pytest.fixture
def raised(world):  # type: ignore[no-untyped-def]
    Organisation.objects.filter(pk=world.org.pk).update(envelope=RAISED)
    return world


def assert_needs_confirmation(response, words: str, step: int, outbox) -> None:  # type: ignore[no-untyped-def]
    assert response.status_code == 409, response.json()
    error = response.json()
    assert error["code"] == "confirmation_required"
    assert f"Step {step}:" in error["error"] and words in error["error"], error
    assert outbox.items() == []


def test_creating_a_mission_beyond_the_defaults_needs_a_confirmation(raised, outbox):
    client = client_for(raised.operator)
    refused = client.post("/api/v1/missions/", body(1500), format="json")
    assert_needs_confirmation(refused, "default maximum distance of 1000 m", 3, outbox)
    high = client.post("/api/v1/missions/", body(100, altitude=200), format="json")
    assert_needs_confirmation(high, "default maximum height of 120 m", 1, outbox)
    assert not Mission.objects.exists()
    created = client.post("/api/v1/missions/", {**body(1500), **CONFIRM}, format="json")
    assert created.status_code == 201, created.json()
    # Within the defaults nothing is asked, raised limits or not.
    assert client.post("/api/v1/missions/", body(500), format="json").status_code == 201


def test_starting_it_asks_again_from_the_chosen_drone(raised, outbox, sent):  # noqa: F811
    online_drone(raised.org, "ACME_A", north=-600)
    client = client_for(raised.operator)
    created = client.post("/api/v1/missions/", body(600), format="json")
    assert created.status_code == 201, created.json()
    start = f"/api/v1/missions/{created.json()['id']}/start/"
    # From a home 600 m south the waypoint is 1 200 m away.
    refused = sent(client.post, start, {"drone": "ACME_A"}, format="json")
    assert_needs_confirmation(refused, "default maximum distance", 3, outbox)
    assert Mission.objects.get().status == "draft" and not Assignment.objects.exists()
    started = sent(client.post, start, {"drone": "ACME_A", **CONFIRM}, format="json")
    assert started.status_code == 200, started.json()
    assert [item["topic"] for item in outbox.items()] == ["ACME_A/mission/in"]


def test_an_imported_plan_beyond_the_defaults_needs_a_confirmation(raised, outbox):
    import json

    from django.core.files.uploadedfile import SimpleUploadedFile

    client = client_for(raised.operator)
    plan = qgc_mission(point_at(-1200, 0), point_at(0, 0))
    refused = client.post("/api/v1/missions/import-plan/", plan, format="json")
    # arm, takeoff, the wait for its height, then the first waypoint: step 3.
    assert_needs_confirmation(refused, "default maximum distance", 3, outbox)
    assert not Mission.objects.exists()

    upload = SimpleUploadedFile("far.plan", json.dumps(plan).encode())
    created = client.post(
        "/api/v1/missions/import-plan/",
        {"file": upload, "confirm_beyond_defaults": "true"},
        format="multipart",
    )
    assert created.status_code == 201, created.json()


def test_a_panic_call_beyond_the_defaults_needs_a_confirmation(raised, outbox, sent):  # noqa: F811
    online_drone(raised.org, "ACME_A")
    lat, lon = point_at(1500, 0)
    client = client_for(raised.operator)
    refused = sent(client.post, "/api/v1/missions/panic/", {"lat": lat, "lon": lon}, format="json")
    assert_needs_confirmation(refused, "default maximum distance", 3, outbox)
    assert not Mission.objects.exists()
    called = sent(
        client.post, "/api/v1/missions/panic/", {"lat": lat, "lon": lon, **CONFIRM}, format="json"
    )
    assert called.status_code == 201, called.json()
    assert [item["topic"] for item in outbox.items()] == ["ACME_A/mission/in"]


def test_the_planner_check_lists_the_steps_to_confirm(raised, outbox):
    response = client_for(raised.operator).post(
        "/api/v1/missions/check-envelope/", {"steps": body(1500)["steps"]}, format="json"
    )
    assert response.status_code == 200, response.json()
    assert response.json()["violations"] == []
    beyond = response.json()["beyond_defaults"]
    assert [(v["index"], v["limit"]) for v in beyond] == [(3, "max_distance")]


def exclusion(north: float, east: float, radius: float) -> dict:
    circle = {"center": list(point_at(north, east)), "radius": radius}
    fence = {"version": 2, "polygons": [], "circles": [{"inclusion": False, "circle": circle}]}
    return {"geoFence": fence, "home": list(point_at(0, 0))}


def test_a_mission_leg_across_an_exclusion_zone_is_refused_and_marked(world, outbox):
    Organisation.objects.filter(pk=world.org.pk).update(envelope=exclusion(100, 0, 20))
    client = client_for(world.operator)
    # Home, then 200 m north: both ends are clear of the zone 100 m north; the leg is not.
    refused = client.post("/api/v1/missions/", body(200), format="json")
    assert refused.status_code == 409, refused.json()
    assert refused.json()["code"] == "outside_envelope"
    assert "Step 3:" in refused.json()["error"]
    assert "exclusion circle 0" in refused.json()["error"]
    assert not Mission.objects.exists() and outbox.items() == []

    checked = client.post(
        "/api/v1/missions/check-envelope/", {"steps": body(200)["steps"]}, format="json"
    ).json()
    [violation] = checked["violations"]
    assert (violation["index"], violation["limit"]) == (3, "geofence")
    (from_lat, _), (to_lat, _) = violation["leg"]
    assert from_lat == pytest.approx(point_at(0, 0)[0]) and to_lat == pytest.approx(
        point_at(200, 0)[0]
    )


def test_a_mission_leg_beside_the_zone_is_accepted(world, outbox):
    Organisation.objects.filter(pk=world.org.pk).update(envelope=exclusion(100, 0, 20))
    lat, lon = point_at(200, 40)
    beside = body(200)
    beside["steps"][3]["params"] = {"lat": lat, "lon": lon}
    beside["steps"][2]["params"] = dict(zip(("lat", "lon"), point_at(0, 40), strict=True))
    # Arrived 40 m east before going north: sent at once, the drone may turn north from
    # home, and that line passes 19.6 m from the zone's centre (its radius is 20 m).
    wait = {
        "command": "wait_for_flight",
        "params": {"horizontal_tolerance": 2, "vertical_tolerance": 2},
    }
    beside["steps"].insert(3, wait)
    created = client_for(world.operator).post("/api/v1/missions/", beside, format="json")
    assert created.status_code == 201, created.json()


def test_a_startchain_beyond_the_defaults_needs_a_confirmation(
    raised,
    outbox,
    sent,  # noqa: F811
):
    import base64
    import json

    from django.test import Client

    online_drone(raised.org, "ACME_1")
    chain = base64.b64encode(json.dumps(body(1500)["steps"]).encode()).decode()
    client = Client()
    client.force_login(raised.operator)
    form = {"command": "startchain", "droneID": "ACME_1", "mission": chain}
    refused = sent(client.post, "/control", form)
    assert refused.status_code == 409, refused.content
    assert refused.json()["code"] == "confirmation_required"
    assert (
        "Step 3:" in refused.json()["error"]
        and "default maximum distance" in (refused.json()["error"])
    )
    assert not Mission.objects.exists() and outbox.items() == []
    started = sent(client.post, "/control", {**form, "confirm_beyond_defaults": "true"})
    assert started.status_code == 200, started.content
    assert [item["topic"] for item in outbox.items()] == ["ACME_1/mission/in"]


def test_a_malformed_confirmation_is_refused_naming_the_field(raised, outbox):
    response = client_for(raised.operator).post(
        "/api/v1/missions/", {**body(1500), "confirm_beyond_defaults": "maybe"}, format="json"
    )
    assert response.status_code == 400, response.json()
    assert "confirm_beyond_defaults" in response.json()["fields"]
    assert not Mission.objects.exists() and outbox.items() == []

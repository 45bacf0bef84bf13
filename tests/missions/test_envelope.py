"""Missions against the flight envelope: every way steps reach a drone is checked first.

A refusal answers 409 `outside_envelope` naming the limit and the step, and nothing is
queued for any drone (the outbox stays empty).
"""

from __future__ import annotations

import json

import pytest
from rest_framework.test import APIClient

from fleet.models import Drone, Organisation
from missions import collaboration, replacement
from missions.creation import create_mission
from missions.errors import MissionError
from missions.models import Assignment, Event, Mission
from missions.planning import coverage, mission_steps
from missions.startstop import start_mission

from .conftest import online_drone, point_at, rectangle
from .test_services import _alarm_event, _complete, _steps


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


@pytest.fixture
def sent(django_capture_on_commit_callbacks):  # type: ignore[no-untyped-def]
    """Run what would be sent after commit, so "nothing was sent" can fail."""

    def run(call, *args, **kwargs):  # type: ignore[no-untyped-def]
        with django_capture_on_commit_callbacks(execute=True):
            return call(*args, **kwargs)

    return run


def body(north: float, altitude: float = 10) -> dict:
    """Take off at home, fly to a point `north` metres away, land."""
    lat, lon = point_at(north, 0)
    home_lat, home_lon = point_at(0, 0)
    return {
        "name": "far",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "navigate", "params": {"lat": home_lat, "lon": home_lon}},
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "land"},
        ],
    }


def assert_refused(response, words: str, step: int, outbox) -> None:  # type: ignore[no-untyped-def]
    assert response.status_code == 409, response.json()
    error = response.json()
    assert error["code"] == "outside_envelope"
    assert f"Step {step}:" in error["error"] and words in error["error"], error
    assert outbox.items() == []


def test_a_mission_leaving_the_envelope_is_refused_at_creation(world, outbox, sent):
    response = client_for(world.operator).post("/api/v1/missions/", body(1500), format="json")
    assert_refused(response, "maximum distance of 1000 m", 3, outbox)
    response = client_for(world.operator).post(
        "/api/v1/missions/", body(100, altitude=200), format="json"
    )
    assert_refused(response, "maximum height of 120 m", 1, outbox)
    assert not Mission.objects.exists()


def test_start_checks_the_steps_from_the_chosen_drone(world, outbox, sent):
    online_drone(world.org, "ACME_A", north=-600)
    mission = client_for(world.operator).post("/api/v1/missions/", body(600), format="json")
    assert mission.status_code == 201, mission.json()
    response = sent(
        client_for(world.operator).post,
        f"/api/v1/missions/{mission.json()['id']}/start/",
        {"drone": "ACME_A"},
        format="json",
    )
    # From a home 600 m south the waypoint is 1 200 m away.
    assert_refused(response, "maximum distance", 3, outbox)
    assert Mission.objects.get().status == "draft" and not Assignment.objects.exists()


def test_a_drone_override_is_applied_at_start(world, outbox, sent):
    drone = online_drone(world.org, "ACME_A")
    Drone.objects.filter(pk=drone.pk).update(max_distance=50.0)
    mission = create_mission(organisation=world.org, name="x", steps=body(100)["steps"])
    with pytest.raises(MissionError) as refused:
        sent(start_mission, mission, drone=Drone.objects.get(pk=drone.pk))
    assert refused.value.status == 409 and "maximum distance of 50 m" in refused.value.message
    assert outbox.items() == []


def qgc_mission(home: tuple, waypoint: tuple, fence: dict | None = None) -> dict:
    """A QGroundControl `.plan`: take off at home, fly to one waypoint."""
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "geoFence": fence or {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {
            "version": 2,
            "firmwareType": 12,
            "vehicleType": 2,
            "cruiseSpeed": 15,
            "hoverSpeed": 5,
            "plannedHomePosition": [*home, 10],
            "items": [
                {
                    "type": "SimpleItem",
                    "command": 22,
                    "frame": 3,
                    "params": [0, 0, 0, None, *home, 10],
                    "autoContinue": True,
                    "doJumpId": 1,
                },
                {
                    "type": "SimpleItem",
                    "command": 16,
                    "frame": 3,
                    "params": [0, 0, 0, None, *waypoint, 10],
                    "autoContinue": True,
                    "doJumpId": 2,
                },
            ],
        },
    }


def test_an_imported_plan_is_checked_from_its_planned_home(world, outbox):
    plan = qgc_mission(point_at(-1200, 0), point_at(0, 0))
    response = client_for(world.operator).post("/api/v1/missions/import-plan/", plan, format="json")
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "outside_envelope"
    assert "maximum distance" in response.json()["error"]
    assert not Mission.objects.exists() and outbox.items() == []


def test_an_imported_plans_own_geofence_is_enforced_and_the_export_writes_the_fence(world):
    exclusion = {"inclusion": False, "circle": {"center": list(point_at(100, 0)), "radius": 20}}
    fence = {"version": 2, "polygons": [], "circles": [{**exclusion, "version": 1}]}
    plan = qgc_mission(point_at(0, 0), point_at(100, 0), fence)
    response = client_for(world.operator).post("/api/v1/missions/import-plan/", plan, format="json")
    assert response.status_code == 409, response.json()
    assert "exclusion circle 0" in response.json()["error"]

    Organisation.objects.filter(pk=world.org.pk).update(envelope={"geoFence": fence})
    plan = qgc_mission(point_at(0, 0), point_at(0, 100))
    created = client_for(world.operator).post("/api/v1/missions/import-plan/", plan, format="json")
    assert created.status_code == 201, created.json()
    exported = client_for(world.operator).get(f"/api/v1/missions/{created.json()['id']}/plan/")
    assert json.loads(exported.content)["geoFence"] == fence


def test_a_panic_call_too_far_away_is_refused(world, outbox, sent):
    online_drone(world.org, "ACME_A")
    lat, lon = point_at(3000, 0)
    response = sent(
        client_for(world.operator).post,
        "/api/v1/missions/panic/",
        {"lat": lat, "lon": lon},
        format="json",
    )
    assert_refused(response, "maximum distance", 3, outbox)
    assert not Mission.objects.exists()


def test_a_replacement_outside_its_envelope_is_not_sent(world, outbox, sent):
    first = online_drone(world.org, "ACME_A")
    second = online_drone(world.org, "ACME_B", north=50)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2, 3])
    Drone.objects.filter(pk=second.pk).update(max_height=5.0)
    outbox.clear()

    replacing = sent(
        replacement.replace_drone,
        mission_id=str(mission.pk),
        assignment_id=str(assignment.pk),
        alarm_event_id=_alarm_event(mission, first).pk,
    )
    assert replacing is None
    decision = mission.events.get(kind=Event.Kind.DECISION, data__code="outside_envelope")
    assert "maximum height of 5 m" in decision.message
    # The failing drone is stopped and landed; the replacement gets nothing.
    assert {item["topic"].split("/")[0] for item in outbox.items()} == {"ACME_A"}


def test_a_collaboration_outside_the_envelope_is_declined(world, outbox, sent):
    area = coverage(rectangle(35, 28), 7)
    alarming = online_drone(world.org, "ACME_A")
    online_drone(world.org, "ACME_B", north=-30)
    online_drone(world.org, "ACME_C", north=-40, east=40)
    mission = create_mission(
        organisation=world.org,
        name="co2",
        steps=mission_steps(area.waypoints, altitude=10),
        extensibility={"vectors": area.vectors.to_dict(), "step_distance": 7},
    )
    assignment = start_mission(mission, drone=alarming).assignment
    Organisation.objects.filter(pk=world.org.pk).update(envelope={"max_distance": 20.0})
    outbox.clear()

    created = sent(
        collaboration.collaborate,
        mission_id=str(mission.pk),
        assignment_id=str(assignment.pk),
        alarm_event_id=_alarm_event(mission, alarming, level="OUT_MEASURE", north=14).pk,
    )
    assert created == []
    decision = mission.events.get(kind=Event.Kind.DECISION, data__decision="collaboration_failed")
    assert "maximum distance of 20 m" in decision.message
    assert outbox.items() == []


def test_the_planner_check_names_every_offending_step(world, outbox):
    online_drone(world.org, "ACME_A", north=-600)
    steps = body(600)["steps"] + [{"command": "altitude", "params": {"value": 500}}]
    response = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", {"steps": steps, "drone": "ACME_A"}, format="json"
    )
    assert response.status_code == 200, response.json()
    found = [(v["index"], v["limit"]) for v in response.json()["violations"]]
    assert found == [(3, "max_distance"), (5, "max_height")]
    alone = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", {"steps": steps}, format="json"
    )
    assert [v["index"] for v in alone.json()["violations"]] == [5]
    assert not Mission.objects.exists() and outbox.items() == []

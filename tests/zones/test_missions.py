"""Published zones on missions: every leg is checked when the mission is created, marked
for the planner, and checked again when it starts (its start is now), like the envelope."""

from __future__ import annotations

import pytest

from missions.models import Assignment, Mission
from tests.missions.conftest import online_drone, point_at
from tests.missions.test_envelope import client_for

from .test_commands import field

pytestmark = pytest.mark.django_db


def through_the_field(altitude: float) -> dict:
    """Take off at home, fly 300 m north across the field (100–200 m north), land."""
    home, beyond = point_at(0, 0), point_at(300, 0)
    return {
        "name": "across",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "navigate", "params": {"lat": home[0], "lon": home[1]}},
            {"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}},
            {"command": "land"},
        ],
    }


def test_a_mission_crossing_the_band_is_refused_and_one_over_it_created(world, outbox):
    field()
    client = client_for(world.operator)
    response = client.post("/api/v1/missions/", through_the_field(40), format="json")
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "zone"
    assert "Step 3: The straight leg to the target crosses" in body["error"]
    assert "'Test field' (LPT-FIELD-1, prohibited, 0 m AGL – 60 m AGL" in body["error"]
    assert not Mission.objects.exists() and outbox.items() == []

    response = client.post("/api/v1/missions/", through_the_field(100), format="json")
    assert response.status_code == 201, response.json()


def test_the_planner_marks_the_leg(world):
    field()
    response = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", through_the_field(40), format="json"
    )
    assert response.status_code == 200, response.json()
    (row,) = response.json()["violations"]
    assert (row["index"], row["limit"]) == (3, "zone")
    assert row["leg"][0] == pytest.approx(list(point_at(0, 0)))


def test_a_zone_published_after_creation_refuses_the_start(world, outbox):
    online_drone(world.org, "ACME_A")
    client = client_for(world.operator)
    mission = client.post("/api/v1/missions/", through_the_field(40), format="json")
    assert mission.status_code == 201, mission.json()
    field()
    response = client.post(
        f"/api/v1/missions/{mission.json()['id']}/start/", {"drone": "ACME_A"}, format="json"
    )
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "zone" and "Step 3:" in response.json()["error"]
    assert Mission.objects.get().status == "draft" and not Assignment.objects.exists()
    assert outbox.items() == []


def test_another_organisations_zone_does_not_refuse_a_mission(world):
    field(world.other_org)
    response = client_for(world.operator).post(
        "/api/v1/missions/", through_the_field(40), format="json"
    )
    assert response.status_code == 201, response.json()

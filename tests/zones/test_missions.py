"""Published zones on missions: every leg is checked when the mission is created, marked
for the planner, and checked again when it starts (its start is now), like the envelope."""

from __future__ import annotations

import pytest

from fleet import envelopes
from missions.models import Assignment, Mission
from tests.missions.conftest import online_drone, point_at
from tests.missions.test_envelope import client_for

from .test_commands import field

pytestmark = pytest.mark.django_db


def through_the_field(altitude: float, wait: bool = True) -> dict:
    """Take off at home (the first waypoint: the plan's home), wait for the height (`wait`),
    fly 300 m north across the field (100–200 m north), land."""
    home, beyond = point_at(0, 0), point_at(300, 0)
    climbed = [{"command": "wait_for_flight"}] if wait else []
    return {
        "name": "across",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "navigate", "params": {"lat": home[0], "lon": home[1]}},
            *climbed,
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
    assert "Step 4: The straight leg to the target crosses" in body["error"]
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
    assert (row["index"], row["limit"]) == (4, "zone")
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
    assert response.json()["code"] == "zone" and "Step 4:" in response.json()["error"]
    assert Mission.objects.get().status == "draft" and not Assignment.objects.exists()
    assert outbox.items() == []


def test_another_organisations_zone_does_not_refuse_a_mission(world):
    field(world.other_org)
    response = client_for(world.operator).post(
        "/api/v1/missions/", through_the_field(40), format="json"
    )
    assert response.status_code == 201, response.json()


def test_a_leg_flown_while_climbing_crosses_a_band_it_passes_over_level(world, outbox):
    """A field from 20 m to 30 m: climbed first, the leg is level at 40 m, over it. Sent at
    once, the drone is surely only 100 / 7.5 = 13.3 m up where the field begins and may be
    anywhere up to 40 m: through the band."""
    field(lowerLimit=20, upperLimit=30)
    client = client_for(world.operator)
    response = client.post("/api/v1/missions/", through_the_field(40), format="json")
    assert response.status_code == 201, response.json()

    response = client.post("/api/v1/missions/", through_the_field(40, wait=False), format="json")
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "zone"
    assert (
        "Step 3: The leg to the target is flown while the drone is still climbing" in body["error"]
    )
    assert "20 m AGL – 30 m AGL" in body["error"]
    assert Mission.objects.count() == 1 and outbox.items() == []


def test_a_mission_started_on_a_drone_still_climbing_flies_its_first_leg_on_the_slant(
    world, outbox
):
    """The drone is 5 m up over home, still climbing to the 40 m it was sent to: the
    mission's first leg, level at 40 m over the 20–30 m field once the climb is done, is
    flown from 5 m on a slant through the band. Done climbing, the same start is sent."""
    field(lowerLimit=20, upperLimit=30)
    beyond = point_at(300, 0)
    steps = [{"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}}]
    client = client_for(world.operator)
    created = client.post("/api/v1/missions/", {"name": "on", "steps": steps}, format="json")
    assert created.status_code == 201, created.json()
    drone = online_drone(world.org, "ACME_A")
    drone.airborne, drone.alt, drone.nav_target = True, 5.0, [0.0, 0.0, -40.0]
    drone.home = [drone.lat, drone.lon]
    drone.save()
    start = f"/api/v1/missions/{created.json()['id']}/start/"
    response = client.post(start, {"drone": "ACME_A"}, format="json")
    assert response.status_code == 409, response.json()
    assert response.json()["code"] == "zone"
    assert (
        "Step 0: The leg to the target is flown while the drone is still climbing"
        in response.json()["error"]
    )
    assert Mission.objects.get().status == "draft" and outbox.items() == []
    drone.alt = 40.0
    drone.save()
    envelopes.check_steps(drone, steps)  # climbed: the leg is level at 40 m, over the band

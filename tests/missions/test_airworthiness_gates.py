"""The platform's own drone choices pass over a drone that is not airworthy: the drones
joining a collaboration and the drone a panic call sends (fleet/airworthiness.py; a
replacement, a manual arm and a mission start are tested with the reasons' apps)."""

from __future__ import annotations

from rest_framework.test import APIClient

from missions import collaboration
from missions.creation import create_mission
from missions.models import Mission
from missions.planning import coverage, mission_steps
from missions.startstop import start_mission

from .conftest import online_drone, outbox, point_at, rectangle  # noqa: F401 (fixture)
from .test_services import _alarm_event

FAILING = {"protocol": "mavlink", "remote_id": {"ok": False, "error": "no operator ID"}}


def _failing(drone):  # type: ignore[no-untyped-def]
    drone.fc = FAILING
    drone.save(update_fields=["fc"])
    return drone


def test_a_collaboration_is_joined_by_the_nearest_airworthy_drone(
    world,
    settings,
    outbox,  # noqa: F811
):
    settings.MISSIONS_JOINING_DRONES = 1
    area = coverage(rectangle(35, 28), 7)
    extensibility = {"vectors": area.vectors.to_dict(), "step_distance": 7}
    alarming = online_drone(world.org, "ACME_A")
    _failing(online_drone(world.org, "ACME_NEAR", north=-30))
    online_drone(world.org, "ACME_FAR", north=-60, east=40)
    mission = create_mission(
        organisation=world.org,
        name="co2",
        steps=mission_steps(area.waypoints, altitude=10),
        extensibility=extensibility,
    )
    assignment = start_mission(mission, drone=alarming).assignment
    alarm = _alarm_event(mission, alarming, level="OUT_MEASURE", north=14)
    created = collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    assert sorted(a.drone.drone_id for a in created) == ["ACME_A", "ACME_FAR"]


def test_a_panic_call_sends_the_nearest_airworthy_drone(world, outbox):  # noqa: F811
    _failing(online_drone(world.org, "ACME_NEAR", north=100))
    far = _failing(online_drone(world.org, "ACME_FAR", north=800))
    lat, lon = point_at(0, 0)
    client = APIClient()
    client.force_authenticate(world.operator)
    body = {"lat": lat, "lon": lon}
    # None airworthy: none is sent, and the call is not kept.
    refused = client.post("/api/v1/missions/panic/", body, format="json")
    assert refused.status_code == 409, refused.json()
    assert not Mission.objects.exists()
    far.fc = {"protocol": "mavlink", "remote_id": {"ok": True}}
    far.save(update_fields=["fc"])
    response = client.post("/api/v1/missions/panic/", body, format="json")
    assert response.status_code == 201, response.json()
    assert response.json()["assignments"][0]["drone"] == "ACME_FAR"

"""The four experiments of [Paula 2018], chapter 5, with MAVLink-simulated drones, and the
self-replacement experiment with a UAVTalk drone replaced by a MAVLink one: the missions
harness and helpers, the real gateway, a real Celery worker."""

from __future__ import annotations

import pytest

from missions.models import Assignment, MissionStatus, Picture, StepStatus
from tests.missions.conftest import point_at, rectangle
from tests.missions.sky import metres
from tests.support.experiments import (  # noqa: F401 - `ground` is a shared fixture
    api,
    completed_waypoints,
    ground,
    survey_with_alarm,
    wait_status,
)
from tests.support.waiting import wait_for

from .sky import MixedSky

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = MixedSky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


def drone_row(drone_id: str):  # type: ignore[no-untyped-def]
    from fleet.models import Drone

    return Drone.objects.get(drone_id=drone_id)


def test_the_panic_button_brings_a_mavlink_drone_to_hover_over_the_caller(world_tx, sky):
    sky.add_drone("ACME_MP1", north=100)
    sky.wait_online()
    assert drone_row("ACME_MP1").fc == {"protocol": "mavlink", "connected": True}
    caller = point_at(0, 0)
    response = api(world_tx.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert response.status_code == 201, response.json()
    mission = wait_status(response.json()["id"], {"completed", "failed", "stopped"}, 60)
    assert mission.status == MissionStatus.COMPLETED

    def hovering_over_caller() -> bool:
        drone = drone_row("ACME_MP1")
        return (
            drone.airborne
            and metres((drone.lat, drone.lon), caller) < 2.0
            and abs(drone.alt - 10.0) < 1.0
        )

    assert wait_for(hovering_over_caller, 10), sky.describe()
    log = api(world_tx.operator).get(f"/api/v1/missions/{mission.pk}/log/").json()
    stages = {s["stage"]: s["duration_s"] for s in log["stages"]}
    # [Paula 2018], §5.1: climbing 10 m at ≤ 2 m/s takes at least 5 s; the whole call
    # under a minute.
    assert stages["takeoff"] >= 4.0 and sum(stages.values()) < 60


def test_aerial_photography_by_a_mavlink_drone_geotags_a_picture_at_each_of_45_waypoints(
    world_tx, sky
):
    sky.add_drone("ACME_MCAM", north=-20, east=-10)
    sky.wait_online()
    body = {
        "name": "photography",
        "altitude": 10,
        "coverage": {
            "vertices": rectangle(64, 32),
            "step_distance": 8,
            "intermediate_action": "takepic",
        },
    }
    client = api(world_tx.operator)
    created = client.post("/api/v1/missions/", body, format="json")
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    assert client.post(f"/api/v1/missions/{mission_id}/start/", format="json").status_code == 200
    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 90)
    assert mission.status == MissionStatus.COMPLETED
    assert mission.steps.filter(command="navigate", status=StepStatus.COMPLETED).count() == 45
    assert wait_for(lambda: Picture.objects.filter(mission=mission).count() == 45, 10)
    pictures = Picture.objects.filter(mission=mission)
    assert all(p.lat is not None and abs(p.alt - 10) < 1.5 for p in pictures)


def test_a_uavtalk_drone_running_out_of_battery_is_replaced_by_a_mavlink_drone(world_tx, sky):
    from missions.planning import coverage, mission_steps

    # A small battery: the UAVTalk drone's fail-safe raises CRITICAL (below 25 %) part
    # way through the survey, as in [Paula 2018], §5.3, and the ground hands its waypoints over.
    sky.add_drone("ACME_UR1", north=-10, fc="uavtalk", battery_capacity_mah=300)
    sky.add_drone("ACME_MR2", north=-40, east=-20, fc="mavlink")
    sky.wait_online()
    area = coverage(rectangle(60, 30), 10)
    steps = mission_steps(area.waypoints, altitude=10)
    client = api(world_tx.operator)
    mission_id = client.post(
        "/api/v1/missions/",
        {
            "name": "replace",
            "steps": [{"command": s["command"], "params": s["params"]} for s in steps],
        },
        format="json",
    ).json()["id"]
    response = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_UR1"}, format="json"
    )
    assert response.status_code == 200, response.json()
    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 90)
    assert mission.status == MissionStatus.COMPLETED
    events = "; ".join(e.message for e in mission.events.exclude(kind="step"))
    assert "CRITICAL from ACME_UR1" in events, events
    replacement = mission.assignments.get(reason=Assignment.Reason.REPLACEMENT)
    assert replacement.drone.drone_id == "ACME_MR2"
    waits = sorted(
        mission.steps.filter(command="wait_for_flight")
        .exclude(index__in=replacement.preparation)
        .values_list("index", flat=True)
    )
    assert len(waits) == len(area.waypoints)
    waypoints = {
        drone: [i for i in indexes if i in waits]
        for drone, indexes in completed_waypoints(mission).items()
    }
    assert sorted(waypoints["ACME_UR1"] + waypoints["ACME_MR2"]) == waits  # none skipped
    assert len(waypoints["ACME_UR1"]) >= 1 and len(waypoints["ACME_MR2"]) >= 1
    assert wait_for(lambda: not drone_row("ACME_UR1").airborne, 20)
    # The ground knows which language each drone of the mixed fleet speaks.
    assert drone_row("ACME_UR1").fc["protocol"] == "uavtalk"
    assert drone_row("ACME_MR2").fc["protocol"] == "mavlink"


def test_collaborative_sensing_by_three_mavlink_drones_extends_the_area_to_56_waypoints(
    world_tx, sky
):
    sky.add_drone("ACME_MC1", north=-10)
    sky.add_drone("ACME_MC2", north=-30, east=20)
    sky.add_drone("ACME_MC3", north=-30, east=45)
    sky.wait_online()
    hold = {"command": "sleep", "params": {"value": 2}}
    steps, extensibility = survey_with_alarm("OUT_MEASURE", 35, 28, 7, after=15, action=hold)
    client = api(world_tx.operator)
    created = client.post(
        "/api/v1/missions/",
        {"name": "co2", "steps": steps, "extensibility": extensibility},
        format="json",
    )
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_MC1"}, format="json")
    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 120)
    assert mission.status == MissionStatus.COMPLETED
    decision = mission.events.get(data__decision="collaboration")
    assert decision.data["waypoints"] == 56
    parts = mission.assignments.filter(reason=Assignment.Reason.COLLABORATION)
    assert sorted(a.drone.drone_id for a in parts) == ["ACME_MC1", "ACME_MC2", "ACME_MC3"]
    new_navigates = mission.steps.filter(
        index__in=[i for a in parts for i in a.step_indexes], command="navigate"
    )
    assert new_navigates.count() == 56
    assert new_navigates.filter(status=StepStatus.COMPLETED).count() == 56
    assert {s.drone.drone_id for s in new_navigates} == {"ACME_MC1", "ACME_MC2", "ACME_MC3"}

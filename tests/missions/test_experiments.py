"""The four experiments of [Paula 2018], chapter 5, end to end, flown by UAVTalk and by
MAVLink drones, plus a mixed fleet, pausing, duplicated alarms and a gateway restart:
simulated drones, the real gateway, a real Celery worker."""

from __future__ import annotations

import time

import pytest

from missions.models import Assignment, Event, Mission, MissionStatus, Picture, StepStatus
from runtime.processes import wait_for
from tests.support.experiments import (  # noqa: F401 - `ground` is a shared fixture
    accepted_completions,
    api,
    completed_waypoints,
    ground,
    redelivered_alarm,
    survey_with_alarm,
    wait_status,
)
from tests.support.ground import publish_as

from .conftest import point_at, rectangle
from .sky import Sky, metres

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
# Each experiment the two flight-controller protocols fly alike, with drone ids of their own
# (the module's broker outlives a test).
PROTOCOLS = pytest.mark.parametrize("fc,tag", [("uavtalk", ""), ("mavlink", "M")])


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = Sky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


def drone_row(drone_id: str):  # type: ignore[no-untyped-def]
    from fleet.models import Drone

    return Drone.objects.get(drone_id=drone_id)


@PROTOCOLS
def test_panic_button_brings_a_disarmed_drone_to_hover_over_the_caller(world_tx, sky, fc, tag):
    drone_id = f"ACME_{tag}P1"
    sky.add_drone(drone_id, north=100, fc=fc)
    sky.wait_online()
    assert drone_row(drone_id).fc["protocol"] == fc and drone_row(drone_id).fc["connected"]
    caller = point_at(0, 0)
    response = api(world_tx.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert response.status_code == 201, response.json()
    mission_id = response.json()["id"]

    def hovering_over_caller() -> bool:
        drone = drone_row(drone_id)
        return (
            drone.airborne
            and metres((drone.lat, drone.lon), caller) < 2.0
            and abs(drone.alt - 10.0) < 1.0
        )

    # On station: the call is not completed until it is released.
    assert wait_for(hovering_over_caller, 60), sky.describe()
    time.sleep(1.0)  # 20 flight seconds on station
    assert Mission.objects.get(pk=mission_id).status == MissionStatus.RUNNING
    assert hovering_over_caller()
    released = api(world_tx.operator).post(f"/api/v1/missions/{mission_id}/release/")
    assert released.json()["status"] == "completed", released.json()
    mission = Mission.objects.get(pk=mission_id)

    def home_disarmed() -> bool:
        drone = drone_row(drone_id)
        return not drone.armed and metres((drone.lat, drone.lon), point_at(100, 0)) < 2.5

    assert wait_for(home_disarmed, 30), sky.describe()
    log = api(world_tx.operator).get(f"/api/v1/missions/{mission.pk}/log/").json()
    stages = {s["stage"]: s["duration_s"] for s in log["stages"]}
    assert set(stages) >= {"arm", "takeoff", "navigate"}
    # [Paula 2018], §5.1: climbing 10 m at ≤ 2 m/s takes at least 5 s; the whole call
    # under a minute.
    assert stages["takeoff"] >= 4.0 and sum(stages.values()) < 60
    assert mission.assignments.get().decode_ms is not None


@PROTOCOLS
def test_aerial_photography_takes_a_geotagged_picture_at_each_of_45_waypoints(
    world_tx, sky, fc, tag
):
    sky.add_drone(f"ACME_{tag}CAM", north=-20, east=-10, fc=fc)
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
    takepics = set(mission.steps.filter(command="takepic").values_list("index", flat=True))
    assert len(takepics) == 45
    # Pictures travel on their own topic; the last may land just after the mission ends.
    assert wait_for(lambda: Picture.objects.filter(mission=mission).count() == 45, 10)
    pictures = Picture.objects.filter(mission=mission)
    assert set(pictures.values_list("index", flat=True)) == takepics
    # wait_for_flight lets the drone be 2 m off vertically when the picture is taken.
    alts = [p.alt for p in pictures]
    assert all(p.lat is not None for p in pictures) and all(abs(a - 10) <= 2.5 for a in alts), alts
    archive = client.get(f"/api/v1/missions/{mission_id}/pictures/odm/")
    assert archive.status_code == 200 and archive["Content-Type"] == "application/zip"


def test_self_replacement_hands_the_remaining_waypoints_to_a_second_drone(world_tx, sky):
    from fleet.models import Drone

    first = sky.add_drone("ACME_R1", north=-10)
    sky.add_drone("ACME_R2", north=-40, east=-20)
    sky.wait_online()
    steps, _ = survey_with_alarm("CRITICAL", 60, 30, 10, after=13)
    client = api(world_tx.operator)
    mission_id = client.post(
        "/api/v1/missions/", {"name": "replace", "steps": steps}, format="json"
    ).json()["id"]
    response = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_R1"}, format="json"
    )
    assert response.status_code == 200, response.json()

    alarm = wait_for(lambda: Event.objects.filter(mission_id=mission_id, kind="alarm").first(), 60)
    assert alarm is not None, sky.describe()
    # The broker delivers the alarm again (QoS 1 redelivery): still one replacement.
    publish_as(first.broker_url, "ACME_R1/alarms/out", redelivered_alarm(alarm, mission_id))

    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 90)
    assert mission.status == MissionStatus.COMPLETED
    # The copy is the same message: recorded once (its message key).
    assert mission.events.filter(kind="alarm").count() == 1
    replacement = mission.assignments.get(reason=Assignment.Reason.REPLACEMENT)
    assert replacement.drone.drone_id == "ACME_R2"
    assert [mission.steps.get(index=i).command for i in replacement.preparation][:2] == [
        "arm",
        "takeoff",
    ]
    assert all(
        mission.steps.get(index=i).drone.drone_id == "ACME_R2" for i in replacement.preparation
    )

    # Waypoints are counted by their wait_for_flight (arrival), preparation left out.
    waits = sorted(
        mission.steps.filter(command="wait_for_flight")
        .exclude(index__in=replacement.preparation)
        .values_list("index", flat=True)
    )
    assert len(waits) == 28
    waypoints = {
        drone: [i for i in indexes if i in waits]
        for drone, indexes in completed_waypoints(mission).items()
    }
    assert sorted(waypoints["ACME_R1"] + waypoints["ACME_R2"]) == waits  # none skipped
    # [Paula 2018], §5.3: 13 by the first drone, 15 by the replacement.
    assert len(waypoints["ACME_R1"]) >= 13 and len(waypoints["ACME_R2"]) >= 1
    completions = accepted_completions(mission)
    assert len(completions) == len(set(completions))  # no step done twice
    # The first drone was told to land and did.
    # Landing may follow a flight home first (a relieved drone returns, then lands).
    assert wait_for(lambda: not Drone.objects.get(drone_id="ACME_R1").airborne, 60)
    decision = mission.events.get(data__decision="replacement")
    # Measured 115-140 ms quiet and 202-436 ms with four busy processes on two cores.
    assert decision.data["since_alarm_ms"] < 5000


def test_a_uavtalk_drone_running_out_of_battery_is_replaced_by_a_mavlink_drone(world_tx, sky):
    from missions.planning import coverage, mission_steps

    # A small battery: the UAVTalk drone's fail-safe raises CRITICAL (below 25 %) part
    # way through the survey, as in [Paula 2018], §5.3, and the ground hands its waypoints
    # over.
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
    # Told to land by the replacement, it lands and disarms itself on the ground.
    assert wait_for(lambda: not drone_row("ACME_UR1").armed and drone_row("ACME_UR1").alt < 0.3, 20)
    # The ground knows which language each drone of the mixed fleet speaks.
    assert drone_row("ACME_UR1").fc["protocol"] == "uavtalk"
    assert drone_row("ACME_MR2").fc["protocol"] == "mavlink"


@PROTOCOLS
def test_collaborative_sensing_extends_the_area_to_56_waypoints_flown_by_three(
    world_tx, sky, fc, tag
):
    from missions.planning import coverage, mission_steps

    # A CO2 plume over waypoint 15 only (its neighbours are 7 m away, outside its 5 m
    # radius); the fail-safe raises OUT_MEASURE above 1000 ppm ([Paula 2018], §5.4).
    area = coverage(rectangle(35, 28), 7)
    assert len(area.waypoints) == 30
    plume_lat, plume_lon = area.waypoints[14]
    sensing = ["--plume", f"{plume_lat},{plume_lon},5,2000,CO2", "--bounds", "CO2::1000"]
    ids = [f"ACME_{tag}C{n}" for n in (1, 2, 3)]
    sky.add_drone(ids[0], north=-10, extra=sensing, fc=fc)
    sky.add_drone(ids[1], north=-30, east=20, extra=sensing, fc=fc)
    sky.add_drone(ids[2], north=-30, east=45, extra=sensing, fc=fc)
    sky.wait_online()
    action = [
        {"command": "sense", "params": {"sensor": "CO2"}},
        {"command": "sleep", "params": {"value": 2}},
    ]
    steps = mission_steps(area.waypoints, altitude=10, intermediate_action=action)
    extensibility = {
        "vectors": area.vectors.to_dict(),
        "step_distance": 7,
        "intermediate_action": action,
    }
    client = api(world_tx.operator)
    created = client.post(
        "/api/v1/missions/",
        {"name": "co2", "steps": steps, "extensibility": extensibility},
        format="json",
    )
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": ids[0]}, format="json")

    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 120)
    assert mission.status == MissionStatus.COMPLETED
    decision = mission.events.get(data__decision="collaboration")
    assert decision.data["waypoints"] == 56
    assert decision.data["area_m2"] == pytest.approx(2058, abs=1)
    parts = mission.assignments.filter(reason=Assignment.Reason.COLLABORATION)
    assert sorted(a.drone.drone_id for a in parts) == ids
    new_navigates = mission.steps.filter(
        index__in=[i for a in parts for i in a.step_indexes], command="navigate"
    )
    assert new_navigates.count() == 56
    assert new_navigates.filter(status=StepStatus.COMPLETED).count() == 56
    flown_by = {s.drone.drone_id for s in new_navigates}
    assert flown_by == set(ids)
    alarming = parts.get(drone__drone_id=ids[0])
    assert alarming.preparation == []
    original = mission.steps.filter(command="navigate").exclude(pk__in=new_navigates)
    assert original.filter(status=StepStatus.COMPLETED).count() >= 15
    assert not original.exclude(status__in=[StepStatus.COMPLETED, StepStatus.SUPERSEDED]).exists()
    # The first alarm came from the reading over waypoint 15; drones crossing the plume
    # again in the new area raise more, which are noted and change nothing.
    first = mission.events.filter(kind="alarm").order_by("at").first()
    assert first.data["level"] == "OUT_MEASURE" and first.data["sensor"] == "CO2"
    assert first.data["value"] > 1000
    wp15 = mission.steps.filter(command="navigate").order_by("index")[14]
    assert (
        metres(
            (first.data["position"]["lat"], first.data["position"]["lon"]),
            (wp15.params["lat"], wp15.params["lon"]),
        )
        < 3
    )


def test_replacement_with_no_drone_available_pauses_then_resumes_when_one_comes_online(
    world_tx, sky
):
    sky.add_drone("ACME_S1")
    sky.wait_online()
    steps, _ = survey_with_alarm("CRITICAL", 20, 10, 10, after=2)
    client = api(world_tx.operator)
    mission_id = client.post(
        "/api/v1/missions/", {"name": "pause", "steps": steps}, format="json"
    ).json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", format="json")
    mission = wait_status(mission_id, {"paused", "completed", "failed"}, 60)
    assert mission.status == MissionStatus.PAUSED
    assert mission.events.filter(data__decision="paused", data__operator_notice=True).exists()

    sky.add_drone("ACME_S2", north=30)
    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 90)
    assert mission.status == MissionStatus.COMPLETED
    assert mission.assignments.get(reason="replacement").drone.drone_id == "ACME_S2"
    waits = mission.steps.filter(command="wait_for_flight")
    assert not waits.exclude(status=StepStatus.COMPLETED).exists()


def test_a_gateway_restart_mid_mission_loses_no_progress(world_tx, sky):
    sky.add_drone("ACME_G1")
    sky.wait_online()
    hold = {"command": "sleep", "params": {"value": 3}}
    steps, _ = survey_with_alarm("OUT_MEASURE", 30, 10, 10, after=99, action=hold)
    steps = [s for s in steps if s["command"] != "virtualalarm"]
    client = api(world_tx.operator)
    mission_id = client.post(
        "/api/v1/missions/", {"name": "restart", "steps": steps}, format="json"
    ).json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", format="json")
    assert wait_for(
        lambda: (
            Mission.objects.get(pk=mission_id)
            .steps.filter(command="sleep", status=StepStatus.COMPLETED)
            .count()
            >= 2
        ),
        60,
    )
    sky.stop_gateway()
    time.sleep(1.0)  # 20 simulated seconds of flight with nobody listening
    sky.start_gateway()
    mission = wait_status(mission_id, {"completed", "failed", "stopped"}, 60)
    assert mission.status == MissionStatus.COMPLETED
    assert set(mission.steps.values_list("status", flat=True)) == {StepStatus.COMPLETED}
    assert set(mission.steps.values_list("drone__drone_id", flat=True)) == {"ACME_G1"}
    # Every step's own report arrived (queued by the broker for the gateway's persistent
    # session), not just the final "mission completed" that implies them.
    assert not mission.steps.filter(duration_s__isnull=True).exists()


def test_a_drone_killed_mid_mission_is_replaced_after_the_grace_period(world_tx, sky, settings):
    """Rule: a drone offline mid-mission shows on the mission at once; still offline after
    MISSIONS_OFFLINE_GRACE_S, it is replaced as for a CRITICAL alarm."""
    from fleet.heartbeats import sweep_offline
    from missions.planning import coverage, mission_steps

    settings.HEARTBEAT_INTERVAL_S = 0.3  # the drones' own interval here
    settings.MISSIONS_OFFLINE_GRACE_S = 3.0
    first = sky.add_drone("ACME_K1", north=-10)
    sky.add_drone("ACME_K2", north=-40, east=-20)
    sky.wait_online()
    steps = mission_steps(coverage(rectangle(60, 30), 10).waypoints, altitude=10)
    client = api(world_tx.operator)
    mission_id = client.post(
        "/api/v1/missions/",
        {"name": "k", "steps": [{"command": s["command"], "params": s["params"]} for s in steps]},
        format="json",
    ).json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_K1"}, format="json")
    mission = Mission.objects.get(pk=mission_id)
    assert wait_for(lambda: len(completed_waypoints(mission).get("ACME_K1", [])) >= 2, 60)
    first.agent.kill()  # a crash: nothing said goodbye

    def shown() -> Event | None:
        sweep_offline()  # stands in for Celery beat's offline sweep
        return mission.events.filter(data__decision="offline").first()

    offline = wait_for(shown, 10)
    assert offline is not None and "ACME_K1 went offline mid-mission" in offline.message
    assert not mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT).exists()
    done = wait_status(mission_id, {"completed", "failed", "stopped"}, 90)
    assert done.status == MissionStatus.COMPLETED, sky.describe()
    replacement = done.assignments.get(reason=Assignment.Reason.REPLACEMENT)
    assert replacement.drone.drone_id == "ACME_K2"
    decided = done.events.get(kind="decision", data__decision="replacement")
    assert (decided.at - offline.at).total_seconds() >= 3.0  # not before the grace period

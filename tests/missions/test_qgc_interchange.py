"""QGroundControl interchange: plans written to QGroundControl's format import, export
and open in QGroundControl (its loaders' rules in tests/missions/qgc_format.py)."""

from __future__ import annotations

import copy
import io
import json
from pathlib import Path

import pytest
from rest_framework.test import APIClient

from missions.errors import MissionError
from missions.models import Mission
from missions.qgc_plan import QgcPlanError, dumps, export_plan, export_qgc_plan, import_plan
from missions.startstop import start_mission
from onboard.protocol import encode_mission_payload

from .conftest import online_drone
from .qgc_format import plan_errors

DATA = Path(__file__).resolve().parents[1] / "data" / "qgc"
PLANS = ["mixed_frames.plan", "fence_rally.plan", "survey_distance.plan"]


def load(name: str) -> dict:
    return json.loads((DATA / name).read_text())


def plain(steps: list[dict]) -> list[dict]:
    """Steps as a drone gets them: without the re-export hints."""
    return [{**s, "params": {k: v for k, v in s["params"].items() if k != "qgc"}} for s in steps]


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def upload(name: str, document: dict | None = None) -> io.BytesIO:
    data = json.dumps(document if document is not None else load(name)).encode()
    handle = io.BytesIO(data)
    handle.name = name
    return handle


# -- the format ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", PLANS)
def test_the_test_plans_themselves_follow_qgroundcontrols_format(name):
    assert plan_errors(load(name)) == []


def test_the_format_checks_catch_what_qgroundcontrol_refuses():
    plan = load("mixed_frames.plan")
    plan["mission"]["plannedHomePosition"] = None
    del plan["mission"]["items"][0]["autoContinue"]
    plan["mission"]["items"][3]["AMSLAltAboveTerrain"] = "high"
    plan["geoFence"]["polygons"] = [{"inclusion": True, "polygon": [[1, 2]], "version": 1}]
    del plan["rallyPoints"]
    errors = "\n".join(plan_errors(plan))
    for fragment in (
        "mission.plannedHomePosition",
        "mission.items[0].autoContinue: missing",
        "mission.items[3].AMSLAltAboveTerrain",
        "geoFence.polygons[0].polygon: fewer than three",
        "file.rallyPoints: missing",
    ):
        assert fragment in errors


@pytest.mark.parametrize("name", PLANS)
def test_exported_plans_open_in_qgroundcontrol(name):
    plan = import_plan(load(name))
    for document in (export_qgc_plan(plan), export_plan(plain(plan.steps), home=plan.home)):
        assert plan_errors(json.loads(dumps(document))) == []


def test_a_plan_without_a_known_home_exports_the_first_waypoint_as_home():
    steps = plain(import_plan(load("fence_rally.plan")).steps)
    document = export_plan(steps)
    assert document["mission"]["plannedHomePosition"] == [40.6306, -8.6575, 0.0]
    assert plan_errors(document) == []
    with pytest.raises(QgcPlanError) as caught:
        export_plan([{"index": 0, "command": "arm", "params": {}}])
    assert caught.value.field == "plannedHomePosition"


# -- import --------------------------------------------------------------------------------


def test_every_simple_item_maps_in_relative_amsl_and_terrain_frames():
    steps = plain(import_plan(load("mixed_frames.plan")).steps)
    by_index = {s["index"]: (s["command"], s["params"]) for s in steps}
    assert by_index[1] == ("takeoff", {"altitude": 15})
    # The autopilot completes a take-off item before the next: the first leg is level.
    assert by_index[2] == ("wait_for_flight", {})
    # AMSL 70 m over a home at 50 m AMSL is 20 m: 5 m above the 15 m takeoff. The speed
    # (DO_CHANGE_SPEED) and region of interest (DO_SET_ROI_LOCATION) ride on the leg.
    assert by_index[3] == (
        "navigate",
        {
            "lat": 40.6306,
            "lon": -8.6572,
            "altitude_delta": 5.0,
            "speed": 4,
            "roi": [40.631, -8.657],
        },
    )
    assert by_index[4] == ("wait_for_flight", {"horizontal_tolerance": 1.5})
    assert by_index[5] == ("takepic", {})  # the trigger's "shoot once now"
    # Calculated above terrain: AMSLAltAboveTerrain 72 m → 22 m, with pictures every 10 m.
    assert by_index[6][1]["altitude_delta"] == 2.0
    assert by_index[7] == ("wait_for_flight", {"photo_distance": 10})
    # Terrain frame (10): AMSLAltAboveTerrain 68 m → 18 m; ROI none; a 5 s loiter.
    assert by_index[8] == (
        "navigate",
        {"lat": 40.6311, "lon": -8.6574, "altitude_delta": -4.0, "speed": 4},
    )
    assert by_index[10] == ("sleep", {"value": 5})
    assert [by_index[i][0] for i in (11, 12)] == ["takepic", "takepic"]  # 2000 and 203
    # VTOL land at AMSL 50 m (ground level), VTOL takeoff to 10 m above terrain.
    assert [by_index[i][0] for i in (13, 14, 15, 16, 17)] == [
        "navigate",
        "wait_for_flight",
        "land",
        "takeoff",
        "wait_for_flight",
    ]
    assert by_index[16][1] == {"altitude": 10.0}
    assert [s["command"] for s in steps[-3:]] == ["navigate", "wait_for_flight", "land"]
    assert (steps[-3]["params"]["lat"], steps[-3]["params"]["lon"]) == (40.6303, -8.6575)
    assert encode_mission_payload("m", "a", steps)  # a mission a drone accepts


def test_a_survey_complex_item_is_flattened_into_its_generated_items():
    plan = import_plan(load("survey_distance.plan"))
    commands = [s["command"] for s in plan.steps]
    assert commands == ["arm", "takeoff", "wait_for_flight", "takepic"] + [
        "navigate",
        "wait_for_flight",
    ] * 5 + ["land"]
    # The take-off's wait comes before the trigger distance is set.
    waits = [s["params"] for s in plan.steps if s["command"] == "wait_for_flight"]
    assert [w.get("photo_distance") for w in waits] == [None, 8, 8, 8, 8, None]


def test_a_complex_item_without_generated_items_is_refused_with_the_reason():
    plan = load("survey_distance.plan")
    del plan["mission"]["items"][1]["TransectStyleComplexItem"]["Items"]
    with pytest.raises(QgcPlanError, match="holds no generated items") as caught:
        import_plan(plan)
    assert caught.value.field == "mission.items[1]"


def test_an_unsupported_item_is_refused_with_its_number_and_command():
    with pytest.raises(QgcPlanError) as caught:
        import_plan(load("unsupported_jump.plan"))
    assert caught.value.field == "mission.items[2]"
    assert "item 3" in caught.value.message and "command 177" in caught.value.message
    servo = load("unsupported_jump.plan")
    del servo["mission"]["items"][2]
    with pytest.raises(QgcPlanError) as caught:
        import_plan(servo)
    assert "item 3" in caught.value.message and "command 183" in caught.value.message


@pytest.mark.parametrize(
    ("mutate", "reason"),
    [
        (lambda items: items[5].update(AMSLAltAboveTerrain=None), "above terrain"),
        (lambda items: items[8].update(AMSLAltAboveTerrain=None), "above terrain"),
        (lambda items: items[9]["params"].__setitem__(0, 2), "region of interest mode"),
        (lambda items: items[3].update(frame=6), "frame 6"),
    ],
)
def test_items_that_cannot_be_flown_are_refused_with_a_reason(mutate, reason):
    plan = copy.deepcopy(load("mixed_frames.plan"))
    mutate(plan["mission"]["items"])
    with pytest.raises(QgcPlanError, match=reason):
        import_plan(plan)


def test_amsl_altitudes_need_the_plans_home():
    plan = load("mixed_frames.plan")
    del plan["mission"]["plannedHomePosition"]
    with pytest.raises(QgcPlanError, match="plannedHomePosition") as caught:
        import_plan(plan)
    assert caught.value.field == "mission.items[3]"


# -- round trips ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", PLANS)
def test_import_export_import_gives_the_same_mission(name):
    plan = import_plan(load(name))
    again = import_plan(json.loads(dumps(export_qgc_plan(plan))))
    assert again.steps == plan.steps
    assert again.geofence == plan.geofence and again.rally_points == plan.rally_points
    # Our own steps (no hints), exported and read back, are the same steps.
    ours = plain(plan.steps)
    assert plain(import_plan(export_plan(ours, home=plan.home)).steps) == ours


def test_our_leg_settings_export_as_speed_roi_and_camera_items():
    steps = plain(import_plan(load("mixed_frames.plan")).steps)
    items = export_plan(steps, home=[40.6303, -8.6575, 50.0])["mission"]["items"]
    commands = [i["command"] for i in items]
    assert commands[:6] == [22, 178, 195, 16, 2000, 206]
    assert items[1]["params"] == [1, 4, -1, 0, 0, 0, 0]
    assert items[2]["params"][4:6] == [40.631, -8.657]
    assert items[5]["params"][0] == 10
    assert 197 in commands
    assert all(i["AltitudeMode"] == 1 and i["frame"] == 3 for i in items if "Altitude" in i)


# -- the API, the fence and the envelope -----------------------------------------------------


def test_an_imported_geofence_becomes_the_missions_fence_and_is_enforced_at_start(world, outbox):
    response = client_for(world.operator).post(
        "/api/v1/missions/import-plan/", {"file": upload("fence_rally.plan")}, format="multipart"
    )
    assert response.status_code == 201, response.json()
    mission = Mission.objects.get(pk=response.json()["id"])
    assert len(mission.fence["polygons"]) == 2 and len(mission.fence["circles"]) == 2
    assert mission.plan_home == [40.6303, -8.6575, 50.0]
    assert world.org.envelope in (None, {})  # the organisation's fence is untouched
    # A drone 600 m away would take off outside the mission's 400 m inclusion circle.
    far = online_drone(world.org, "ACME_FAR", north=0)
    far.lat, far.lon = 40.6357, -8.6575
    far.save()
    with pytest.raises(MissionError) as caught:
        start_mission(mission, drone=far)
    assert caught.value.code == "outside_envelope"
    assert Mission.objects.get(pk=mission.pk).status == "draft"
    exported = json.loads(
        client_for(world.viewer).get(f"/api/v1/missions/{mission.pk}/plan/").content
    )
    assert plan_errors(exported) == []
    assert exported["mission"]["plannedHomePosition"] == [40.6303, -8.6575, 50.0]
    assert len(exported["geoFence"]["polygons"]) == 2


def test_an_admin_may_make_the_plans_fence_the_organisations(world):
    url = "/api/v1/missions/import-plan/?fence=organisation"
    refused = client_for(world.operator).post(
        url, {"file": upload("fence_rally.plan")}, format="multipart"
    )
    assert refused.status_code == 403
    assert Mission.objects.count() == 0
    accepted = client_for(world.owner).post(
        url, {"file": upload("fence_rally.plan")}, format="multipart"
    )
    assert accepted.status_code == 201, accepted.json()
    world.org.refresh_from_db()
    assert len(world.org.envelope["geoFence"]["polygons"]) == 2
    assert Mission.objects.get().fence is None


def test_a_refused_plan_creates_nothing_and_names_the_item(world):
    response = client_for(world.owner).post(
        "/api/v1/missions/import-plan/?fence=organisation",
        {"file": upload("unsupported_jump.plan")},
        format="multipart",
    )
    assert response.status_code == 400
    assert "item 3" in json.dumps(response.json()) and "177" in json.dumps(response.json())
    assert Mission.objects.count() == 0


def test_a_plan_outside_the_organisations_envelope_changes_nothing(world):
    world.org.envelope = {"max_distance": 20}
    world.org.save()
    response = client_for(world.owner).post(
        "/api/v1/missions/import-plan/?fence=organisation",
        {"file": upload("fence_rally.plan")},
        format="multipart",
    )
    assert response.status_code in (400, 409), response.json()
    world.org.refresh_from_db()
    assert world.org.envelope == {"max_distance": 20}
    assert Mission.objects.count() == 0


def test_a_plan_round_trips_through_the_api_with_its_leg_settings(world):
    client = client_for(world.operator)
    first = client.post(
        "/api/v1/missions/import-plan/", {"file": upload("mixed_frames.plan")}, format="multipart"
    )
    assert first.status_code == 201, first.json()
    steps = first.json()["steps"]
    navigate = next(s for s in steps if s["command"] == "navigate")
    assert navigate["params"]["speed"] == 4 and navigate["params"]["roi"] == [40.631, -8.657]
    assert {"photo_distance": 10}.items() <= steps[7]["params"].items()
    exported = client.get(f"/api/v1/missions/{first.json()['id']}/plan/")
    assert plan_errors(json.loads(exported.content)) == []
    again = client.post(
        "/api/v1/missions/import-plan/",
        {"file": upload("again.plan", json.loads(exported.content))},
        format="multipart",
    )
    assert again.status_code == 201, again.json()
    strip = [{k: s[k] for k in ("index", "command", "params")} for s in steps]
    assert [
        {k: s[k] for k in ("index", "command", "params")} for s in again.json()["steps"]
    ] == strip

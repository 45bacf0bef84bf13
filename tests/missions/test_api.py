"""The missions REST API with personas: operator, viewer, outsider; bad input gets 4xx."""

from __future__ import annotations

import io
import json
import zipfile

import pytest
from rest_framework.test import APIClient

from logs.importers.base import Limits
from logs.importers.mission import MissionLogImporter
from missions.creation import create_mission
from missions.models import Mission, MissionStatus

from .conftest import online_drone, point_at, rectangle


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def _mission_body(**extra: object) -> dict:
    lat, lon = point_at(20, 0)
    return {
        "name": "survey",
        "altitude": 10,
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 10}},
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "wait_for_flight"},
            {"command": "land"},
        ],
        **extra,
    }


def test_coverage_of_the_photography_area_has_45_waypoints(world):
    body = {"vertices": rectangle(64, 32), "step_distance": 8, "altitude": 10}
    response = client_for(world.operator).post("/api/v1/missions/coverage/", body, format="json")
    assert response.status_code == 200, response.json()
    data = response.json()
    assert len(data["waypoints"]) == 45
    assert data["area_m2"] == pytest.approx(2048, rel=1e-3)
    assert data["step_distance"] == 8 and set(data["vectors"]) == {"v", "w"}


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (
            {"vertices": [[40.0, -8.0], [40.0, -8.0001], [40.0, -8.0002]], "step_distance": 8},
            "vertices",
        ),
        ({"vertices": rectangle(64, 32), "step_distance": 0}, "step_distance"),
        (
            {"vertices": [[95.0, 0.0], [40.0, -8.0], [40.1, -8.0]], "step_distance": 8},
            "vertices[0]",
        ),
        ({"vertices": rectangle(5000, 5000), "step_distance": 1}, "step_distance"),
        ({"vertices": rectangle(64, 32), "step_distance": 8, "altitude": -3}, "altitude"),
    ],
)
def test_bad_coverage_input_is_a_400_naming_the_field(world, body, field):
    response = client_for(world.operator).post("/api/v1/missions/coverage/", body, format="json")
    assert response.status_code == 400
    error = response.json()
    assert error["error"].startswith(field) or field in error["fields"], error


def test_extension_of_the_sensing_area_has_56_waypoints_in_three_parts(world):
    center = point_at(14, 17.5)
    body = {
        "vertices": rectangle(35, 28),
        "step_distance": 7,
        "altitude": 7,
        "center": list(center),
        "joining_drones": 2,
    }
    response = client_for(world.operator).post(
        "/api/v1/missions/coverage/extend/", body, format="json"
    )
    assert response.status_code == 200, response.json()
    data = response.json()
    assert len(data["waypoints"]) == 56 and data["area_m2"] == pytest.approx(2058, abs=1)
    assert sorted(i for part in data["parts"] for i in part) == list(range(56))
    assert len(data["parts"]) == 3


def test_an_operator_creates_and_starts_a_mission_on_a_chosen_drone(world, outbox):
    online_drone(world.org, "ACME_1")
    client = client_for(world.operator)
    created = client.post("/api/v1/missions/", _mission_body(), format="json")
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    assert [s["index"] for s in created.json()["steps"]] == [0, 1, 2, 3, 4]
    started = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_1"}, format="json"
    )
    assert started.status_code == 200, started.json()
    assert started.json()["status"] == "running"
    assert started.json()["assignments"][0]["drone"] == "ACME_1"
    steps = client.get(f"/api/v1/missions/{mission_id}/steps/").json()
    assert [s["status"] for s in steps] == ["pending"] * 5


def test_a_mission_from_a_coverage_keeps_its_extensibility_parameters(world):
    body = {
        "name": "co2",
        "altitude": 7,
        "coverage": {
            "vertices": rectangle(35, 28),
            "step_distance": 7,
            "intermediate_action": {"command": "sleep", "params": {"value": 2}},
        },
    }
    response = client_for(world.operator).post("/api/v1/missions/", body, format="json")
    assert response.status_code == 201, response.json()
    mission = Mission.objects.get(pk=response.json()["id"])
    assert mission.steps.filter(command="navigate").count() == 30
    assert mission.extensibility["step_distance"] == 7 and "vectors" in mission.extensibility


@pytest.mark.parametrize(
    ("steps", "field"),
    [
        ([{"command": "warp"}], "steps[0].command"),
        ([{"command": "navigate", "params": {"lat": 12.0}}], "steps[0].params.lon"),
        ([{"command": "navigate", "params": {"lat": 12.0, "lon": 181}}], "steps[0].params.lon"),
        ([{"command": "sleep", "params": {"value": -1}}], "steps[0].params.value"),
        ([], "steps"),
        ("arm", "steps"),
    ],
)
def test_invalid_steps_are_a_400_naming_the_field_and_nothing_is_created(world, steps, field):
    response = client_for(world.operator).post(
        "/api/v1/missions/", {"name": "bad", "steps": steps}, format="json"
    )
    assert response.status_code == 400
    assert field in response.json()["fields"], response.json()
    assert not Mission.objects.exists()


def test_another_organisations_drone_cannot_be_given_a_mission(world, outbox):
    online_drone(world.other_org, "GLOBEX_7")
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    response = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "GLOBEX_7"}, format="json"
    )
    assert response.status_code == 404 and "drone" in response.json()["fields"]
    assert Mission.objects.get(pk=mission_id).status == MissionStatus.DRAFT
    assert outbox.items() == []


def test_an_offline_drone_cannot_be_chosen(world, outbox):
    drone = online_drone(world.org, "ACME_OFF")
    drone.online = False
    drone.save()
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    response = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_OFF"}, format="json"
    )
    assert response.status_code == 409 and "offline" in response.json()["error"]


def test_a_viewer_cannot_start_and_an_outsider_cannot_see_a_mission(world, outbox):
    online_drone(world.org, "ACME_1")
    mission_id = (
        client_for(world.operator)
        .post("/api/v1/missions/", _mission_body(), format="json")
        .json()["id"]
    )
    assert client_for(world.viewer).post(f"/api/v1/missions/{mission_id}/start/").status_code == 403
    assert (
        client_for(world.viewer)
        .post("/api/v1/missions/", _mission_body(), format="json")
        .status_code
        == 403
    )
    assert client_for(world.outsider).get(f"/api/v1/missions/{mission_id}/").status_code == 404
    assert (
        client_for(world.outsider).post(f"/api/v1/missions/{mission_id}/stop/").status_code == 404
    )


def test_stop_marks_the_mission_stopped_and_queues_a_stop_for_its_drone(
    world, outbox, django_capture_on_commit_callbacks
):
    online_drone(world.org, "ACME_1")
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    with django_capture_on_commit_callbacks(execute=True):
        client.post(f"/api/v1/missions/{mission_id}/start/", format="json")
        response = client.post(f"/api/v1/missions/{mission_id}/stop/")
    assert response.status_code == 200 and response.json()["status"] == "stopped"
    actions = [item["payload"]["action"] for item in outbox.items()]
    assert actions == ["start", "stop"]


def test_the_mission_log_is_read_by_the_log_importer(world, outbox, tmp_path):
    online_drone(world.org, "ACME_1")
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    client.post(f"/api/v1/missions/{mission_id}/start/", format="json")
    response = client.get(f"/api/v1/missions/{mission_id}/log/")
    assert response.status_code == 200
    doc = response.json()
    assert doc["mission"]["id"] == mission_id and doc["drones"][0]["id"] == "ACME_1"
    assert doc["assignments"][0]["reason"] == "initial"
    path = tmp_path / "log.json"
    path.write_text(json.dumps(doc))
    importer = MissionLogImporter()
    assert importer.sniff(path, path.read_bytes()[:4096])
    log = importer.read(path, limits=Limits(), progress=lambda fraction: None)
    assert log.metadata["mission"]["id"] == mission_id


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"{not json", "is not JSON"),
        (b'{"events": []}', "not a mission log"),
        (b'{"mission": {}, "events": [{"ts": "yesterday"}]}', "events[0].ts"),
        (b'{"mission": {}, "events": [{"ts": 1, "position": {"lat": 100, "lon": 0}}]}', "lat"),
        (b"\xff\xfe", "UTF-8"),
    ],
)
def test_a_malformed_mission_log_upload_is_refused_with_the_reason(world, content, reason):
    upload = io.BytesIO(content)
    upload.name = "log.json"
    response = client_for(world.viewer).post(
        "/api/v1/missions/logs/check/", {"file": upload}, format="multipart"
    )
    assert response.status_code == 400
    assert reason in response.json()["error"], response.json()


def test_a_well_formed_mission_log_upload_comes_back_for_the_viewer(world):
    doc = {
        "mission": {"id": "m"},
        "drones": [{"id": "A"}],
        "events": [{"ts": 1.0, "drone_id": "A", "position": {"lat": 40.6, "lon": -8.6}}],
    }
    upload = io.BytesIO(json.dumps(doc).encode())
    upload.name = "log.json"
    response = client_for(world.viewer).post(
        "/api/v1/missions/logs/check/", {"file": upload}, format="multipart"
    )
    assert response.status_code == 200 and response.json()["events"][0]["drone_id"] == "A"


def test_a_qgroundcontrol_plan_round_trips_through_the_api(world):
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    exported = client.get(f"/api/v1/missions/{mission_id}/plan/")
    assert exported.status_code == 200
    plan = json.loads(exported.content)
    assert plan["fileType"] == "Plan"
    upload = io.BytesIO(exported.content)
    upload.name = "survey.plan"
    imported = client.post("/api/v1/missions/import-plan/", {"file": upload}, format="multipart")
    assert imported.status_code == 201, imported.json()
    commands = [s["command"] for s in imported.json()["steps"]]
    assert "navigate" in commands and commands[-1] == "land"


def test_a_broken_plan_file_is_refused_with_the_reason(world):
    upload = io.BytesIO(b'{"fileType": "Plan", "version": 1, "mission": {"version": 1}}')
    upload.name = "old.plan"
    response = client_for(world.operator).post(
        "/api/v1/missions/import-plan/", {"file": upload}, format="multipart"
    )
    assert response.status_code == 400 and "mission.version" in response.json()["error"]


def test_the_panic_button_sends_the_nearest_drone_to_the_caller_at_ten_metres(world, outbox):
    online_drone(world.org, "ACME_FAR", north=800)
    online_drone(world.org, "ACME_NEAR", north=100)
    lat, lon = point_at(0, 0)
    response = client_for(world.operator).post(
        "/api/v1/missions/panic/", {"lat": lat, "lon": lon}, format="json"
    )
    assert response.status_code == 201, response.json()
    data = response.json()
    assert data["assignments"][0]["drone"] == "ACME_NEAR"
    assert [s["command"] for s in data["steps"]] == [
        "arm",
        "takeoff",
        "wait_for_flight",
        "navigate",
        "wait_for_flight",
        "sleep",  # on station until released
    ]
    assert data["steps"][1]["params"]["altitude"] == 10


def test_a_released_panic_call_completes_and_sends_its_drone_home(
    world, outbox, django_capture_on_commit_callbacks
):
    online_drone(world.org, "ACME_NEAR", north=100)
    lat, lon = point_at(0, 0)
    client = client_for(world.operator)
    with django_capture_on_commit_callbacks(execute=True):
        call = client.post("/api/v1/missions/panic/", {"lat": lat, "lon": lon}, format="json")
    assert call.json()["status"] == "running"
    outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        released = client.post(f"/api/v1/missions/{call.json()['id']}/release/")
    assert released.status_code == 200 and released.json()["status"] == "completed"
    [item] = outbox.items()
    assert item["topic"] == "ACME_NEAR/mission/in"
    assert item["payload"]["action"] == "stop" and item["payload"]["then"] == "return"
    again = client.post(f"/api/v1/missions/{call.json()['id']}/release/")
    assert again.status_code == 409 and "already completed" in again.json()["error"]


def test_only_a_panic_call_is_released(world, outbox):
    mission = create_mission(organisation=world.org, name="survey", steps=[{"command": "arm"}])
    response = client_for(world.operator).post(f"/api/v1/missions/{mission.pk}/release/")
    assert response.status_code == 409 and "only a panic call" in response.json()["error"]


def test_a_panic_call_without_a_position_is_refused(world):
    response = client_for(world.operator).post(
        "/api/v1/missions/panic/", {"lat": "here"}, format="json"
    )
    assert response.status_code == 400 and "lat" in response.json()["fields"]
    assert not Mission.objects.exists()


def test_the_openapi_schema_lists_the_mission_endpoints(world):
    response = client_for(world.operator).get("/api/schema/", HTTP_ACCEPT="application/json")
    assert response.status_code == 200
    paths = (
        json.loads(response.content)["paths"]
        if response["Content-Type"].startswith("application/json")
        else None
    )
    if paths is None:
        import yaml  # drf-spectacular depends on PyYAML

        paths = yaml.safe_load(response.content)["paths"]
    for path in (
        "/api/v1/missions/coverage/",
        "/api/v1/missions/coverage/extend/",
        "/api/v1/missions/{id}/start/",
        "/api/v1/missions/{id}/stop/",
        "/api/v1/missions/{id}/log/",
        "/api/v1/missions/panic/",
        "/api/v1/missions/{id}/release/",
        "/api/v1/missions/import-plan/",
        "/api/v1/missions/{id}/plan/",
    ):
        assert path in paths, path


def test_the_odm_archive_holds_every_picture_and_geo_txt(world):
    from tests.missions.test_pictures import store_sample_picture

    mission = Mission.objects.create(organisation=world.org, name="photos")
    drone = online_drone(world.org, "ACME_CAM")
    for i in range(3):
        store_sample_picture(drone, mission, i)
    response = client_for(world.viewer).get(f"/api/v1/missions/{mission.pk}/pictures/odm/")
    assert response.status_code == 200
    archive = zipfile.ZipFile(io.BytesIO(response.content))
    names = archive.namelist()
    assert sum(n.startswith("images/") for n in names) == 3
    geo = archive.read("geo.txt").decode().splitlines()
    assert geo[0] == "EPSG:4326" and len(geo) == 4
    listed = client_for(world.viewer).get(f"/api/v1/missions/{mission.pk}/pictures/").json()
    assert len(listed) == 3 and listed[0]["thumbnail_url"].endswith("/thumbnail/")


def test_the_mission_list_filters_by_status_name_and_drone(world, outbox):
    from django.test import Client

    online_drone(world.org, "ACME_1")
    client = client_for(world.operator)
    flown = client.post("/api/v1/missions/", _mission_body(name="flown"), format="json").json()
    client.post("/api/v1/missions/", _mission_body(name="draft only"), format="json")
    client.post(f"/api/v1/missions/{flown['id']}/start/", {"drone": "ACME_1"}, format="json")
    browser = Client()
    browser.force_login(world.viewer)
    by_drone = browser.get("/missions/", {"drone": "ACME_1"}).content.decode()
    assert "flown" in by_drone and "draft only" not in by_drone
    by_status = browser.get("/missions/", {"status": "draft"}).content.decode()
    assert "draft only" in by_status and ">flown<" not in by_status
    by_name = browser.get("/missions/", {"q": "draft"}).content.decode()
    assert "draft only" in by_name and ">flown<" not in by_name

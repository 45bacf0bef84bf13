"""Pre-flight checklists on the real database: templates refused naming the field, the
roles, a mission start and an arm refused with 409 checklist_required until a checklist
passes (and again once it expires), automatic items measured from live data, drone
selection for the platform's own work, the audit trail and the flight record."""

from __future__ import annotations

import time
from datetime import timedelta

import pytest
from django.utils import timezone
from rest_framework.test import APIClient

from accounts.models import AuditEvent
from checklists import runs
from checklists.models import Policy, Run, Template
from missions.selection import nearest_available
from telemetry.storage import Sample
from tests.missions.conftest import online_drone, outbox, point_at  # noqa: F401 (fixture)
from tests.records.support import fly, store

pytestmark = pytest.mark.django_db

ITEMS = [
    {"kind": "manual", "text": "Propellers tight, no cracks"},
    {"kind": "auto", "check": "battery", "threshold": 0.6},
    {"kind": "auto", "check": "airworthy"},
]


def api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


@pytest.fixture
def template(world):  # type: ignore[no-untyped-def]
    """The organisation requires checklists and has one template."""
    Policy.objects.create(organisation=world.org, required=True, valid_minutes=30)
    body = {"name": "Before flight", "items": ITEMS}
    response = api(world.owner).post("/api/v1/organisations/acme/checklists/", body, format="json")
    assert response.status_code == 201, response.content
    return response.json()


def run(user, drone_id: str, template: dict, answers: list[bool]):  # type: ignore[no-untyped-def]
    body = {"template": template["id"], "answers": answers}
    return api(user).post(f"/api/v1/drones/{drone_id}/checklists/", body, format="json")


def start(user, drone_id: str):  # type: ignore[no-untyped-def]
    lat, lon = point_at(20, 0)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 10}},
        {"command": "navigate", "params": {"lat": lat, "lon": lon}},
        {"command": "land"},
    ]
    client = api(user)
    created = client.post("/api/v1/missions/", {"name": "m", "steps": steps}, format="json")
    mission_id = created.json()["id"]
    return client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": drone_id}, format="json")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"items": []}, "items"),
        ({"valid_minutes": -5}, "valid_minutes"),
        ({"items": [{"kind": "auto", "check": "weather"}]}, "items[0].check"),
        ({"items": [{"kind": "auto", "check": "battery", "threshold": 7}]}, "items[0].threshold"),
        ({"items": [{"kind": "manual", "text": " "}]}, "items[0].text"),
    ],
)
def test_a_bad_template_is_refused_naming_the_field_and_changes_nothing(world, change, field):
    body = {"name": "Before flight", "items": ITEMS, **change}
    response = api(world.owner).post("/api/v1/organisations/acme/checklists/", body, format="json")
    assert response.status_code == 400
    assert list(response.json()["fields"]) == [field]
    assert not Template.objects.exists()
    assert not AuditEvent.objects.filter(action="checklist.template").exists()


def test_admins_define_operators_run_viewers_read_outsiders_see_nothing(world, template):
    body = {"name": "Other", "items": ITEMS}
    operator = api(world.operator)
    assert (
        operator.post("/api/v1/organisations/acme/checklists/", body, format="json").status_code
        == 403
    )
    assert run(world.viewer, "ACME_1", template, [True]).status_code == 403
    assert api(world.viewer).get("/api/v1/drones/ACME_1/checklists/").status_code == 200
    assert api(world.outsider).get("/api/v1/drones/ACME_1/checklists/").status_code == 404
    assert api(world.outsider).get("/api/v1/organisations/acme/checklists/").status_code == 404
    assert run(world.outsider, "ACME_1", template, [True]).status_code == 404
    assert Template.objects.count() == 1 and not Run.objects.exists()


def test_a_mission_start_needs_a_passed_checklist(world, template, outbox):  # noqa: F811
    online_drone(world.org, "ACME_1", battery=0.9)
    refused = start(world.operator, "ACME_1")
    assert refused.status_code == 409
    assert refused.json()["code"] == "checklist_required"
    assert "ACME_1" in refused.json()["error"]
    assert outbox.items() == []

    passed = run(world.operator, "ACME_1", template, [True])
    assert passed.status_code == 201 and passed.json()["passed"], passed.json()
    battery = passed.json()["results"][1]
    assert battery["check"] == "battery" and battery["value"] == 0.9 and battery["threshold"] == 0.6
    started = start(world.operator, "ACME_1")
    assert started.status_code in (200, 201), started.content
    entry = AuditEvent.objects.get(action="checklist.run")
    assert entry.outcome == "ok" and entry.actor_name == "operator"
    assert entry.detail["results"][0] == {
        "kind": "manual",
        "text": ITEMS[0]["text"],
        "passed": True,
    }


def test_an_expired_checklist_is_refused(world, template, outbox):  # noqa: F811
    drone = online_drone(world.org, "ACME_1", battery=0.9)
    long_ago = timezone.now() - timedelta(minutes=31)
    Run.objects.create(
        organisation=world.org, drone=drone, template_id=template["id"], template_name="Before flight",
        results=[], passed=True, at=long_ago, expires_at=long_ago + timedelta(minutes=30),
    )  # fmt: skip
    refused = start(world.operator, "ACME_1")
    assert refused.status_code == 409 and refused.json()["code"] == "checklist_required"
    assert "expired" in refused.json()["error"]


def test_an_automatic_item_below_its_threshold_fails_the_checklist_and_the_arm(world, template):
    online_drone(world.org, "ACME_1", battery=0.5)
    failed = run(world.operator, "ACME_1", template, [True])
    assert failed.status_code == 201
    assert not failed.json()["passed"]
    assert failed.json()["failures"] == ["battery charge at least: battery at 50%, 60% needed"]
    arm = api(world.operator).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm", "params": {}}, format="json"
    )
    assert arm.status_code == 409 and arm.json()["code"] == "checklist_required"
    assert "failed" in arm.json()["error"]
    assert AuditEvent.objects.get(action="checklist.run").outcome == "failed"


def test_an_unconfirmed_item_fails_and_a_wrong_answer_count_is_refused(world, template):
    online_drone(world.org, "ACME_1", battery=0.9)
    assert run(world.operator, "ACME_1", template, [True, True]).json()["fields"] == {
        "answers": ["must be a list of 1 true/false values"]
    }
    assert not Run.objects.exists()
    assert run(world.operator, "ACME_1", template, [False]).json()["failures"] == [
        "not confirmed: Propellers tight, no cracks"
    ]


def test_the_gps_item_reads_the_newest_telemetry(world, template):
    drone = online_drone(world.org, "ACME_1")
    item = {"kind": "auto", "check": "gps", "threshold": 6}
    from checklists.checks import measure

    assert measure(drone, item).why == "no GPS telemetry received"
    fields = {"Status": "Fix3D", "Satellites": 5}
    store([Sample(time.time() - 1, drone.pk, "GPSPosition", fields)])
    assert measure(drone, item).why == "5 satellites, 6 needed"
    store([Sample(time.time(), drone.pk, "GPSPosition", {**fields, "Satellites": 9})])
    assert measure(drone, item).passed


def test_the_wind_item_reads_the_flight_controllers_estimate(world, template):
    from checklists.checks import measure

    drone = online_drone(world.org, "ACME_1")
    item = {"kind": "auto", "check": "wind", "threshold": None}
    assert measure(drone, item).why == "no wind estimate reported"
    drone.fc = {"protocol": "mavlink", "wind": {"speed": 14.0}}
    assert "above this drone's limit of 10 m/s" in measure(drone, item).why
    drone.fc = {"protocol": "mavlink", "wind": {"speed": 3.0}}
    assert measure(drone, item).passed


def test_the_zones_item_asks_the_published_zones_about_a_take_off_here(world, template):
    from checklists.checks import measure
    from tests.zones.test_commands import INSIDE, field

    field()
    drone = online_drone(world.org, "ACME_1")
    drone.lat, drone.lon = INSIDE
    item = {"kind": "auto", "check": "zones", "threshold": 10}
    assert "LPT-FIELD-1" in measure(drone, item).why
    drone.lat, drone.lon = 40.6303, -8.6575
    assert measure(drone, item).passed


def test_the_platforms_own_choice_skips_a_drone_failing_an_automatic_item(world, template):
    online_drone(world.org, "ACME_NEAR", north=5, battery=0.5)
    online_drone(world.org, "ACME_FAR", north=200, battery=0.9)
    chosen = nearest_available(world.org.pk, target=point_at(0, 0))
    assert [d.drone_id for d in chosen] == ["ACME_FAR"]
    Policy.objects.filter(organisation=world.org).update(required=False)
    chosen = nearest_available(world.org.pk, target=point_at(0, 0))
    assert [d.drone_id for d in chosen] == ["ACME_NEAR"]


def test_a_panic_call_needs_no_run_but_skips_a_drone_failing_an_automatic_item(
    world,
    template,
    outbox,  # noqa: F811
):
    online_drone(world.org, "ACME_NEAR", north=100, battery=0.5)
    online_drone(world.org, "ACME_FAR", north=800, battery=0.9)
    lat, lon = point_at(0, 0)
    body = {"lat": lat, "lon": lon}
    response = api(world.operator).post("/api/v1/missions/panic/", body, format="json")
    assert response.status_code == 201, response.json()
    assert response.json()["assignments"][0]["drone"] == "ACME_FAR"
    assert not Run.objects.exists()


def test_the_flight_record_names_the_checklist_it_flew_on(world, template):
    drone = online_drone(world.org, "ACME_1", battery=0.9)
    checked = runs.run_checklist(
        drone, {"template": template["id"], "answers": [True]}, world.operator
    )
    record, _ = fly(drone, time.time() + 1)
    event = record.events[0]
    assert event["kind"] == "checklist" and event["source"] == f"checklist:{checked.pk}"
    assert event["checklist"]["results"][1]["value"] == 0.9


def test_runs_cannot_be_changed(world, template):
    drone = online_drone(world.org, "ACME_1")
    checked = runs.run_checklist(drone, {"template": template["id"], "answers": [True]}, None)
    with pytest.raises(PermissionError):
        checked.save()
    with pytest.raises(PermissionError):
        Run.objects.filter(pk=checked.pk).update(passed=False)

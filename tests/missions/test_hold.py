"""Operator pause and resume of a running mission through the API: who may, when, and what
reaches the drones."""

from __future__ import annotations

import pytest

from fleet.models import Drone
from missions import live
from missions.models import Event, Mission
from missions.progress import apply_progress
from missions.sending import send_assignment
from onboard import protocol

from .conftest import online_drone
from .test_api import _mission_body, client_for


@pytest.fixture
def running(world, outbox, django_capture_on_commit_callbacks):
    online_drone(world.org, "ACME_1")
    client = client_for(world.operator)
    mission_id = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    with django_capture_on_commit_callbacks(execute=True):
        client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_1"}, format="json")
    outbox.clear()
    return mission_id


def test_pause_then_resume_reaches_the_drone_records_events_and_pushes_them(
    world, outbox, running, django_capture_on_commit_callbacks, monkeypatch
):
    pushed = []
    monkeypatch.setattr(live, "push", lambda pk, payload: pushed.append(payload))
    client = client_for(world.operator)
    for action, held in (("pause", True), ("resume", False)):
        with django_capture_on_commit_callbacks(execute=True):
            response = client.post(f"/api/v1/missions/{running}/{action}/")
        assert response.status_code == 200, response.json()
        assert response.json()["held"] is held and response.json()["status"] == "running"
    sent = [(item["topic"], item["payload"]) for item in outbox.items()]
    assert [(t, p["action"]) for t, p in sent] == [
        ("ACME_1/mission/in", "pause"),
        ("ACME_1/mission/in", "resume"),
    ]
    for _, payload in sent:
        assert protocol.parse_mission_request(payload).mission_id == running
    events = Event.objects.filter(mission_id=running, kind=Event.Kind.OPERATOR)
    assert [e.data["action"] for e in events.order_by("at")] == ["pause", "resume"]
    assert [p["data"]["action"] for p in pushed if p.get("kind") == "operator"] == [
        "pause",
        "resume",
    ]


def test_a_second_pause_and_a_resume_of_a_running_mission_are_409_and_change_nothing(
    world, outbox, running
):
    client = client_for(world.operator)
    assert client.post(f"/api/v1/missions/{running}/resume/").status_code == 409
    assert client.post(f"/api/v1/missions/{running}/pause/").status_code == 200
    again = client.post(f"/api/v1/missions/{running}/pause/")
    assert again.status_code == 409 and "already paused" in str(again.json())
    assert Mission.objects.get(pk=running).held is True
    assert Event.objects.filter(mission_id=running, kind=Event.Kind.OPERATOR).count() == 1


def test_a_draft_mission_cannot_be_paused_and_only_its_operators_may(world, outbox):
    client = client_for(world.operator)
    draft = client.post("/api/v1/missions/", _mission_body(), format="json").json()["id"]
    refused = client.post(f"/api/v1/missions/{draft}/pause/")
    assert refused.status_code == 409 and "not running" in str(refused.json())
    assert client_for(world.viewer).post(f"/api/v1/missions/{draft}/pause/").status_code == 403
    assert client_for(world.outsider).post(f"/api/v1/missions/{draft}/pause/").status_code == 404
    assert Mission.objects.get(pk=draft).held is False
    assert outbox.items() == []


def test_a_drone_held_from_its_page_holds_its_assignment_until_resumed(world, running):
    mission = Mission.objects.get(pk=running)
    assignment = mission.assignments.get()
    drone = Drone.objects.get(drone_id="ACME_1")
    for status, held in (("paused", True), ("resumed", False)):
        message = protocol.MissionProgress(running, str(assignment.pk), status)
        assert apply_progress(drone, message) is None
        mission.refresh_from_db()
        assignment.refresh_from_db()
        # The drone holds, not the mission: the operator did not pause it.
        assert (assignment.held, mission.held, mission.status) == (held, False, "running")
    assert assignment.status == "sent"  # a pause is no assignment state


def test_a_drone_refusing_a_pause_does_not_reject_its_assignment(world, running):
    drone = Drone.objects.get(drone_id="ACME_1")
    refusal = protocol.mission_reply(
        protocol.mission_pause(running, "pause"), "rejected", error="not running"
    )
    assert apply_progress(drone, refusal) is None
    mission = Mission.objects.get(pk=running)
    assert mission.status == "running"
    assert mission.assignments.get().status == "sent"


def test_a_drone_sent_to_a_paused_mission_is_paused_right_after_its_start(world, outbox, running):
    assert client_for(world.operator).post(f"/api/v1/missions/{running}/pause/").status_code == 200
    outbox.clear()
    send_assignment(Mission.objects.get(pk=running).assignments.get())
    assert [item["payload"]["action"] for item in outbox.items()] == ["start", "pause"]

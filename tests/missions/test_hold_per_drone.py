"""Holding one drone of a multi-drone mission: the rest fly on.

Rule: a drone held from its own page (or through the API with `drone`) holds alone; its
assignment records it, and the mission is not marked paused. The mission's Pause holds
every drone still flying, and its Resume lets every held drone carry on.
"""

from __future__ import annotations

import pytest

from fleet.models import Drone
from missions.creation import create_mission
from missions.models import Assignment, Mission
from missions.progress import apply_progress
from missions.startstop import start_mission
from onboard import protocol

from .conftest import online_drone
from .test_api import _mission_body, client_for


def two_drone_mission(org):  # type: ignore[no-untyped-def]
    """A running mission: ACME_A flies steps 0-2 (the returned assignment), ACME_B 3-4."""
    first = online_drone(org, "ACME_A")
    second = online_drone(org, "ACME_B", north=20)
    mission = create_mission(organisation=org, name="pair", steps=_mission_body()["steps"])
    assignment = start_mission(mission, drone=first).assignment
    Assignment.objects.filter(pk=assignment.pk).update(step_indexes=[0, 1, 2])
    Assignment.objects.create(
        mission=mission,
        drone=second,
        step_indexes=[3, 4],
        reason=Assignment.Reason.COLLABORATION,
        status=Assignment.Status.ACCEPTED,
    )
    return mission, assignment


@pytest.fixture
def pair(world, outbox, django_capture_on_commit_callbacks):  # type: ignore[no-untyped-def]
    """A running mission flown by ACME_A (steps 0-2) and ACME_B (steps 3-4)."""
    mission, assignment = two_drone_mission(world.org)
    outbox.clear()
    return mission


def held(mission: Mission) -> dict[str, bool]:
    rows = Assignment.objects.filter(mission=mission).select_related("drone")
    return {a.drone.drone_id: a.held for a in rows}


def sent(outbox) -> list[tuple[str, str]]:  # type: ignore[no-untyped-def]
    return [(i["topic"].split("/")[0], i["payload"]["action"]) for i in outbox.items()]


def report(mission: Mission, drone_id: str, status: str) -> None:
    drone = Drone.objects.get(drone_id=drone_id)
    assignment = mission.assignments.get(drone=drone)
    message = protocol.MissionProgress(str(mission.pk), str(assignment.pk), status)
    assert apply_progress(drone, message) is None


def test_a_drone_held_from_its_page_holds_alone_and_the_mission_pause_holds_the_rest(
    world, pair, outbox, django_capture_on_commit_callbacks
):
    report(pair, "ACME_A", "paused")  # its page's Hold: the agent paused its mission
    pair.refresh_from_db()
    assert held(pair) == {"ACME_A": True, "ACME_B": False}
    assert (pair.held, pair.status) == (False, "running")
    detail = client_for(world.operator).get(f"/api/v1/missions/{pair.pk}/").json()
    assert {a["drone"]: a["held"] for a in detail["assignments"]} == held(pair)

    client = client_for(world.operator)
    with django_capture_on_commit_callbacks(execute=True):
        paused = client.post(f"/api/v1/missions/{pair.pk}/pause/")
    assert paused.status_code == 200 and paused.json()["held"] is True
    assert sent(outbox) == [("ACME_B", "pause")]  # ACME_A holds already
    assert held(pair) == {"ACME_A": True, "ACME_B": True}

    outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        resumed = client.post(f"/api/v1/missions/{pair.pk}/resume/")
    assert resumed.status_code == 200 and resumed.json()["held"] is False
    assert sorted(sent(outbox)) == [("ACME_A", "resume"), ("ACME_B", "resume")]
    assert held(pair) == {"ACME_A": False, "ACME_B": False}


def test_the_api_holds_and_resumes_one_drone_of_the_mission(
    world, pair, outbox, django_capture_on_commit_callbacks
):
    client = client_for(world.operator)
    url = f"/api/v1/missions/{pair.pk}"
    with django_capture_on_commit_callbacks(execute=True):
        paused = client.post(f"{url}/pause/", {"drone": "ACME_B"}, format="json")
    assert paused.status_code == 200, paused.json()
    assert paused.json()["held"] is False  # the mission is not paused
    assert sent(outbox) == [("ACME_B", "pause")]
    assert held(pair) == {"ACME_A": False, "ACME_B": True}
    again = client.post(f"{url}/pause/", {"drone": "ACME_B"}, format="json")
    assert again.status_code == 409 and "already holding" in again.json()["error"]
    stranger = client.post(f"{url}/pause/", {"drone": "ACME_Z"}, format="json")
    assert stranger.status_code == 409 and "not flying this mission" in stranger.json()["error"]

    outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        resumed = client.post(f"{url}/resume/", {"drone": "ACME_B"}, format="json")
    assert resumed.status_code == 200, resumed.json()
    assert sent(outbox) == [("ACME_B", "resume")]
    assert held(pair) == {"ACME_A": False, "ACME_B": False}
    assert client.post(f"{url}/resume/", {"drone": "ACME_B"}, format="json").status_code == 409
    assert client.post(f"{url}/resume/").status_code == 409  # nobody holds


def test_the_mission_pause_ends_when_its_last_held_drone_resumes(
    world, pair, outbox, django_capture_on_commit_callbacks
):
    client = client_for(world.operator)
    assert client.post(f"/api/v1/missions/{pair.pk}/pause/").status_code == 200
    report(pair, "ACME_A", "resumed")  # resumed from its own page
    pair.refresh_from_db()
    assert pair.held is True and held(pair) == {"ACME_A": False, "ACME_B": True}
    with django_capture_on_commit_callbacks(execute=True):
        one = client.post(f"/api/v1/missions/{pair.pk}/resume/", {"drone": "ACME_B"}, format="json")
    assert one.status_code == 200 and one.json()["held"] is False
    assert held(pair) == {"ACME_A": False, "ACME_B": False}

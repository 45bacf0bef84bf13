"""The seed's four experiments end to end (seed 001, ch. 5), plus pausing, duplicated
alarms and a gateway restart: simulated drones, the real gateway, a real Celery worker."""

from __future__ import annotations

import json
import time

import pytest
from rest_framework.test import APIClient

from missions.models import Assignment, Event, Mission, MissionStatus, Picture, StepStatus

from .conftest import point_at, rectangle
from .sky import Sky, Worker, metres, wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture(scope="module")
def worker(django_db_setup, django_db_blocker, tmp_path_factory):  # type: ignore[no-untyped-def]
    from django.db import connection

    with django_db_blocker.unblock():
        name = connection.settings_dict["NAME"]
    w = Worker(name, tmp_path_factory.mktemp("worker"))
    yield w
    w.stop()


@pytest.fixture
def sky(world_tx, worker, tmp_path):  # type: ignore[no-untyped-def]
    s = Sky(tmp_path, world_tx.org.slug).start()
    yield s
    s.close()


def api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def wait_status(mission_id: str, wanted: set[str], timeout: float) -> Mission:
    def done() -> Mission | None:
        mission = Mission.objects.get(pk=mission_id)
        return mission if mission.status in wanted else None

    mission = wait_for(done, timeout, interval=0.2)
    if mission is None:
        mission = Mission.objects.get(pk=mission_id)
        events = list(mission.events.values_list("message", flat=True))[-15:]
        raise AssertionError(f"mission is {mission.status}; last events: {events}")
    return mission


def completed_waypoints(mission: Mission) -> dict[str, list[int]]:
    """Waypoints (their wait_for_flight step indexes) per drone that completed them."""
    per: dict[str, list[int]] = {}
    for step in mission.steps.filter(command="wait_for_flight", status=StepStatus.COMPLETED):
        per.setdefault(step.drone.drone_id, []).append(step.index)
    return per


def accepted_completions(mission: Mission) -> list[int]:
    """Step indexes of every completion the ground accepted (not ignored as duplicates)."""
    return [
        e.data["index"]
        for e in mission.events.filter(kind=Event.Kind.STEP, data__status="completed")
        if not e.data.get("ignored")
    ]


def test_panic_button_brings_a_disarmed_drone_to_hover_over_the_caller(world_tx, sky):
    sky.add_drone("ACME_P1", north=100)
    sky.wait_online()
    caller = point_at(0, 0)
    response = api(world_tx.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert response.status_code == 201, response.json()
    mission = wait_status(response.json()["id"], {"completed", "failed", "stopped"}, 60)
    assert mission.status == MissionStatus.COMPLETED

    from fleet.models import Drone

    def hovering_over_caller() -> bool:
        drone = Drone.objects.get(drone_id="ACME_P1")
        return (
            drone.airborne
            and metres((drone.lat, drone.lon), caller) < 2.0
            and abs(drone.alt - 10.0) < 1.0
        )

    assert wait_for(hovering_over_caller, 10), sky.describe()
    log = api(world_tx.operator).get(f"/api/v1/missions/{mission.pk}/log/").json()
    stages = {s["stage"]: s["duration_s"] for s in log["stages"]}
    assert set(stages) >= {"arm", "takeoff", "navigate"}
    # Seed 5.1: climbing 10 m at ≤ 2 m/s takes at least 5 s; the whole call under a minute.
    assert stages["takeoff"] >= 4.0 and sum(stages.values()) < 60
    assert mission.assignments.get().decode_ms is not None

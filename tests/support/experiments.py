"""What the experiments share, whichever drones fly them: the module's ground (a
private broker and a Celery worker, tests/missions/sky.py), the operator's API client,
waiting for a mission's status, the survey missions they fly and what they leave behind.

Used by tests/missions/test_experiments.py (UAVTalk and MAVLink drones) and by the
replicated ground (tests/support/ground.py). Django is imported inside the functions, so
importing this module needs no settings.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from rest_framework.test import APIClient

    from missions.models import Mission


@pytest.fixture(scope="module")
def ground(django_db_setup, django_db_blocker, tmp_path_factory):  # type: ignore[no-untyped-def]
    """One broker and Celery worker for the module, on the test database."""
    from django.db import connection

    from tests.missions.sky import Ground

    with django_db_blocker.unblock():
        name = connection.settings_dict["NAME"]
    g = Ground(tmp_path_factory.mktemp("ground"), name)
    yield g
    g.close()


def api(user: Any) -> APIClient:
    from rest_framework.test import APIClient

    client = APIClient()
    client.force_authenticate(user)
    return client


def wait_status(mission_id: str, wanted: set[str], timeout: float) -> Mission:
    from missions.models import Mission
    from runtime.processes import wait_for

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
    from missions.models import StepStatus

    per: dict[str, list[int]] = {}
    for step in mission.steps.filter(command="wait_for_flight", status=StepStatus.COMPLETED):
        per.setdefault(step.drone.drone_id, []).append(step.index)
    return per


def accepted_completions(mission: Mission) -> list[int]:
    """Step indexes of every completion the ground accepted (not ignored as duplicates)."""
    from missions.models import Event

    return [
        e.data["index"]
        for e in mission.events.filter(kind=Event.Kind.STEP, data__status="completed")
        if not e.data.get("ignored")
    ]


def survey_with_alarm(
    level: str,
    width: float,
    height: float,
    step: float,
    after: int,
    action: Any = None,
    *,
    message: str = "test alarm",
) -> tuple[list[dict], dict]:
    """Survey steps with a virtual alarm right after waypoint `after` (1-based) is done,
    and the mission's extensibility."""
    from missions.planning import coverage, mission_steps
    from tests.missions.planning import rectangle

    area = coverage(rectangle(width, height), step)
    steps = mission_steps(area.waypoints, altitude=10, intermediate_action=action)
    per_waypoint = 2 + (1 if action else 0)
    at = 2 + per_waypoint * after
    alarm = {"command": "virtualalarm", "params": {"level": level, "message": message}}
    steps = [{"command": s["command"], "params": s["params"]} for s in steps]
    steps.insert(at, alarm)
    extensibility = {
        "vectors": area.vectors.to_dict(),
        "step_distance": step,
        "intermediate_action": action,
    }
    return steps, extensibility


def redelivered_alarm(alarm: Any, mission_id: str) -> dict:
    """The alarm message the drone sent, rebuilt from its event, to publish once more as
    the broker would redeliver it (QoS 1)."""
    return {
        "type": "alarm",
        "level": "CRITICAL",
        "message": alarm.data["message"],
        "ts": alarm.data["ts"],
        "position": alarm.data["position"],
        "mission_id": mission_id,
        "assignment_id": alarm.data["assignment"],
        "index": alarm.data["index"],
        "sensor": None,
        "value": None,
    }

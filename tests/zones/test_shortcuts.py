"""Published zones against legs sent before the last one ends: a `navigate` sent while the
one before it is still under way (no `wait_for_flight` between them) may be flown from
anywhere along that one (onboard/envelope.py `fan_origins`), so a mission whose corner
goes round a zone but whose shortcut crosses it is refused; waiting at the corner, the
same mission is created."""

from __future__ import annotations

import pytest

from missions.models import Mission
from tests.missions.conftest import point_at
from tests.missions.test_envelope import client_for

from .test_commands import field

pytestmark = pytest.mark.django_db
WAIT = {
    "command": "wait_for_flight",
    "params": {"horizontal_tolerance": 2, "vertical_tolerance": 2},
}


def round_the_field(*between: dict) -> dict:
    """At 40 m (in the field's 0–60 m band) from home to 150 m north 100 m east of it,
    east of the field (100–200 m north, 50 m either side), then to 300 m north, beyond
    it: both legs pass the field, the straight line home → 300 m north crosses it."""
    home, corner, beyond = point_at(0, 0), point_at(150, 100), point_at(300, 0)
    return {
        "name": "round the field",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 40}},
            {"command": "navigate", "params": {"lat": home[0], "lon": home[1]}},
            WAIT,
            {"command": "navigate", "params": {"lat": corner[0], "lon": corner[1]}},
            *between,
            {"command": "navigate", "params": {"lat": beyond[0], "lon": beyond[1]}},
            {"command": "land"},
        ],
    }


def test_a_mission_cutting_the_corner_across_a_zone_is_refused_and_waiting_creates_it(
    world, outbox
):
    field()
    client = client_for(world.operator)
    response = client.post("/api/v1/missions/", round_the_field(), format="json")
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "zone"
    assert "Step 5: The straight leg to the target crosses" in body["error"], body
    assert "'Test field' (LPT-FIELD-1" in body["error"]
    # A sleep waits a time, not an arrival: still refused.
    slept = round_the_field({"command": "sleep", "params": {"value": 5}})
    response = client.post("/api/v1/missions/", slept, format="json")
    assert response.status_code == 409 and "Step 6:" in response.json()["error"]
    assert not Mission.objects.exists() and outbox.items() == []

    response = client.post("/api/v1/missions/", round_the_field(WAIT), format="json")
    assert response.status_code == 201, response.json()


def test_the_planner_marks_the_step_and_a_leg_across_the_zone(world):
    field()
    response = client_for(world.operator).post(
        "/api/v1/missions/check-envelope/", round_the_field(), format="json"
    )
    assert response.status_code == 200, response.json()
    rows = response.json()["violations"]
    # One row for the step, however many of its fan legs cross the zone.
    assert [(row["index"], row["limit"]) for row in rows] == [(5, "zone")]
    # The leg drawn ends at the step's target and starts on the unfinished leg before it.
    (start_lat, start_lon), end = rows[0]["leg"]
    assert end == pytest.approx(list(point_at(300, 0)))
    home, corner = point_at(0, 0), point_at(150, 100)
    assert min(home[0], corner[0]) - 1e-6 <= start_lat <= max(home[0], corner[0]) + 1e-6
    assert min(home[1], corner[1]) - 1e-6 <= start_lon <= max(home[1], corner[1]) + 1e-6

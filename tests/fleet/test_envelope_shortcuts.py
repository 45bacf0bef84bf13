"""The geofence against legs sent before the last one ends, through the REST API: a
`navigate` sent while the one before it is still under way (no `wait_for_flight` between
them) may be flown from anywhere along that one (onboard/envelope.py `fan_origins`), so a
mission round the inside corner of a concave (L-shaped) inclusion fence whose shortcut
leaves the fence is refused, at creation and at its start; waiting at the corner it is
created and started."""

from __future__ import annotations

import pytest

from fleet import envelopes
from missions.models import Assignment, Mission
from onboard.envelope import ned_to_latlon
from tests.missions.conftest import online_drone, outbox, point_at  # noqa: F401
from tests.missions.test_envelope import client_for

pytestmark = pytest.mark.django_db
HOME = point_at(0, 0)
WAIT = {
    "command": "wait_for_flight",
    "params": {"horizontal_tolerance": 2, "vertical_tolerance": 2},
}
# A strip 40 m wide up the north axis to 120 m, and one 40 m wide east along 80–120 m
# north: home → 100 m north → then 80 m east stays inside; home → there straight does not.
L_FENCE = [(-20, -20), (120, -20), (120, 100), (80, 100), (80, 20), (-20, 20)]


def fence_the_l(organisation) -> None:  # type: ignore[no-untyped-def]
    polygon = [list(ned_to_latlon(n, e, HOME)) for n, e in L_FENCE]
    fence = {"version": 2, "polygons": [{"inclusion": True, "polygon": polygon, "version": 1}]}
    envelopes.set_envelope(organisation, {"home": list(HOME), "geoFence": fence})


def round_the_corner(*between: dict) -> dict:
    north, corner = point_at(100, 0), point_at(100, 80)
    return {
        "name": "round the corner",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 10}},
            WAIT,
            {"command": "navigate", "params": {"lat": north[0], "lon": north[1]}},
            *between,
            {"command": "navigate", "params": {"lat": corner[0], "lon": corner[1]}},
            {"command": "land"},
        ],
    }


def assert_cut_corner(response, step: int) -> None:  # type: ignore[no-untyped-def]
    assert response.status_code == 409, response.json()
    body = response.json()
    assert body["code"] == "outside_envelope", body
    assert f"Step {step}: The straight leg to the target leaves the geofence" in body["error"]
    assert "wait_for_flight" in body["error"], body


def test_cutting_the_inside_corner_of_the_fence_is_refused_at_creation(world, outbox):  # noqa: F811
    fence_the_l(world.org)
    client = client_for(world.operator)
    assert_cut_corner(client.post("/api/v1/missions/", round_the_corner(), format="json"), 4)
    slept = round_the_corner({"command": "sleep", "params": {"value": 5}})
    assert_cut_corner(client.post("/api/v1/missions/", slept, format="json"), 5)
    assert not Mission.objects.exists() and outbox.items() == []
    created = client.post("/api/v1/missions/", round_the_corner(WAIT), format="json")
    assert created.status_code == 201, created.json()


def test_a_fence_drawn_after_creation_refuses_the_start_from_the_drone(world, outbox):  # noqa: F811
    online_drone(world.org, "ACME_A")
    client = client_for(world.operator)
    cutting = client.post("/api/v1/missions/", round_the_corner(), format="json")
    waiting = client.post("/api/v1/missions/", round_the_corner(WAIT), format="json")
    assert cutting.status_code == waiting.status_code == 201
    fence_the_l(world.org)
    url = "/api/v1/missions/{}/start/"
    refused = client.post(url.format(cutting.json()["id"]), {"drone": "ACME_A"}, format="json")
    assert_cut_corner(refused, 4)
    assert not Assignment.objects.exists() and outbox.items() == []
    started = client.post(url.format(waiting.json()["id"]), {"drone": "ACME_A"}, format="json")
    assert started.status_code == 200, started.json()

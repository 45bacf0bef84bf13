"""Send in the planner, in a real browser: it sends the plan as the form reads when it is
pressed, and a mission once however often it is pressed."""

from __future__ import annotations

import time

import pytest

from missions.models import Mission, MissionStatus
from tests.conftest import login

from .conftest import online_drone, rectangle

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

COVERAGE = "**/api/v1/missions/coverage/"


def planned(page, live_asgi, world) -> None:  # type: ignore[no-untyped-def]
    """The planner with a 64 × 32 m area covered every 8 m, its drone online."""
    online_drone(world.org, "ACME_1", north=-20)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    page.wait_for_function("window.skyhivePlanner && window.skyhivePlanner.map")
    page.fill("#step-distance", "8")
    page.press("#step-distance", "Tab")
    page.evaluate(
        "(pts) => pts.forEach((p) => window.skyhivePlanner.map.fire('click', {latlng: L.latLng(p[0], p[1])}))",
        rectangle(64.5, 32.5),
    )
    page.wait_for_function("document.getElementById('waypoint-count').textContent === '45'")


def test_a_field_left_by_pressing_send_is_sent_as_it_reads(page, live_asgi, world_tx):
    planned(page, live_asgi, world_tx)
    held = []

    def hold(route) -> None:  # type: ignore[no-untyped-def]
        held.append(route)

    page.route(COVERAGE, hold)
    # Still in the field when Send is pressed: leaving it asks for the area again, and that
    # answer is held back while Send goes on.
    page.fill("#step-distance", "16")
    page.click("#send-mission")
    deadline = time.monotonic() + 10.0  # the request goes as Send is pressed
    while not held and time.monotonic() < deadline:
        page.wait_for_timeout(20)
    assert len(held) == 1
    # A check and a creation take well under a second here; nothing is sent meanwhile.
    page.wait_for_timeout(1000)
    assert not Mission.objects.exists()

    held[0].continue_()
    page.unroute(COVERAGE, hold)
    page.wait_for_url("**/missions/*-*/")
    mission = Mission.objects.get()
    assert mission.extensibility["step_distance"] == 16
    assert mission.status == MissionStatus.RUNNING


def test_send_pressed_twice_sends_one_mission(page, live_asgi, world_tx):
    planned(page, live_asgi, world_tx)
    page.dblclick("#send-mission")
    page.wait_for_url("**/missions/*-*/")
    page.wait_for_selector("#live-status.ok")
    assert Mission.objects.count() == 1

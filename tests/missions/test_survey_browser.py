"""The planner's camera survey in a real browser: a known camera and area give the spacings,
waypoints and estimates worked out by hand, and the drones appear on the map."""

from __future__ import annotations

import pytest

from tests.conftest import login
from tests.support.screenshots import docs_screenshot

from .conftest import online_drone, point_at, rectangle
from .test_pages_browser import centre_map, click_at

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_a_camera_survey_sets_spacings_height_and_estimates(page, live_asgi, world_tx):
    drone = online_drone(world_tx.org, "ACME_1", north=-20, battery=0.8)
    drone.sensors = {"CAMERA": "DJI Phantom 4 Pro"}
    drone.save()
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    page.wait_for_selector("#planner-map .planner-drone")
    page.check("#survey-enabled")
    # The drone's own camera is preselected from its gear.
    page.wait_for_function("document.getElementById('survey-preset').value === 'DJI Phantom 4 Pro'")
    page.select_option("#survey-mode", "height")
    page.fill("#survey-height", "100")
    page.fill("#survey-overlap", "80")
    page.fill("#survey-sidelap", "70")
    page.select_option("#drone-choice", "ACME_1")
    centre_map(page, *point_at(45, 50))
    # 100 m along the lines, 90 m across: 150 × 100 m footprint, lines 45 m apart and
    # photos every 20 m → 6 photos on each of 3 lines.
    for lat, lon in rectangle(101, 91):  # a click lands within a pixel (~0.4 m)
        click_at(page, lat, lon)
    page.wait_for_function("document.getElementById('waypoint-count').textContent === '18'")
    result = page.locator("#survey-result").inner_text()
    assert "45.0 m" in result and "20.0 m" in result and "150.0 × 100.0 m" in result
    assert "2.74 cm/px" in result
    assert "Battery (ACME_1)" in result
    docs_screenshot(page, "planner", height=1000)
    assert page.locator("#altitude").input_value() == "100.0"
    assert page.locator("#step-distance").input_value() == "20.0"
    # arm, takeoff, 18 × (navigate, wait, takepic), land — summarised, list one click away.
    assert page.locator("#step-summary").inner_text() == "57 steps · 18 waypoints · 18 photos"
    assert not page.locator("#step-list").is_visible()
    page.click("#step-details summary")
    assert page.locator("#step-list .step").count() == 57

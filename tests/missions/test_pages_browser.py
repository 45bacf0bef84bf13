"""The mission pages in a real browser: planner, mission page, log viewer, panic button."""

from __future__ import annotations

import json

import pytest

from missions.models import Mission, MissionStatus
from tests.conftest import login

from .conftest import online_drone, point_at, rectangle

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def centre_map(page, lat: float, lon: float) -> None:  # type: ignore[no-untyped-def]
    # No animation: a click's pixel must map to the same place as when it was computed.
    page.evaluate(
        "([lat, lon]) => window.skyhivePlanner.map.setView([lat, lon], 18, {animate: false})",
        [lat, lon],
    )


def click_at(page, lat: float, lon: float) -> None:  # type: ignore[no-untyped-def]
    """Click the planner's map where (lat, lon) is drawn."""
    x, y = page.evaluate(
        "([lat, lon]) => { const p = window.skyhivePlanner.map.latLngToContainerPoint([lat, lon]);"
        " return [p.x, p.y]; }",
        [lat, lon],
    )
    box = page.locator("#planner-map").bounding_box()
    page.mouse.click(box["x"] + x, box["y"] + y)


def test_the_planner_turns_three_clicks_into_45_waypoints_and_sends_the_mission(
    page, live_asgi, world_tx
):
    online_drone(world_tx.org, "ACME_1", north=-20)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    centre_map(page, *point_at(16, 32))
    page.fill("#step-distance", "8")
    page.select_option("#intermediate-action", "takepic")
    # Half a metre to spare: a click lands on a pixel (about 0.4 m here), not on a point.
    for lat, lon in rectangle(64.5, 32.5):
        click_at(page, lat, lon)
    page.wait_for_function("document.getElementById('waypoint-count').textContent === '45'")
    assert page.locator("#planner-map .waypoint").count() == 45
    # arm, takeoff, 45 × (navigate, wait, takepic), land
    assert page.locator("#step-list .step").count() == 2 + 45 * 3 + 1

    # The list is summarised, one click away; open it and drag take-off above arm, then
    # back: the list is editable by drag and drop.
    assert "45 waypoints" in page.locator("#step-summary").inner_text()
    # The height profile is drawn above the list once the plan is checked: drag after it
    # has appeared, or the list moves under the pointer mid-drag.
    page.wait_for_selector("#height-profile:not([hidden])")
    page.click("#step-details summary")
    commands = page.locator("#step-list .step select.command")
    steps = page.locator("#step-list .step")
    # Each change of the list is checked again (the profile above it is redrawn): the
    # second drag starts once that answer is drawn.
    with page.expect_response(lambda r: "/check-envelope/" in r.url):
        steps.nth(1).locator(".handle").drag_to(steps.nth(0).locator(".handle"))
    page.evaluate(
        "() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))"
    )
    assert [commands.nth(i).input_value() for i in range(2)] == ["takeoff", "arm"]
    steps.nth(1).locator(".handle").drag_to(steps.nth(0).locator(".handle"))
    assert [commands.nth(i).input_value() for i in range(2)] == ["arm", "takeoff"]
    # Each command has its parameter form: the take-off altitude is editable.
    assert steps.nth(1).locator("input[name=altitude]").input_value() == "10"

    page.fill("#mission-name", "Campus survey")
    page.click("#send-mission")
    page.wait_for_url("**/missions/*-*/")
    mission = Mission.objects.get(name="Campus survey")
    assert mission.status == MissionStatus.RUNNING
    assert mission.steps.count() == 2 + 45 * 3 + 1
    assert mission.extensibility["step_distance"] == 8
    assert mission.assignments.get().drone.drone_id == "ACME_1"
    page.wait_for_selector("#live-status.ok")
    assert "ACME_1" in page.locator("#drone-progress").inner_text()


def test_the_planner_shows_the_reason_when_the_area_is_a_line(page, live_asgi, world_tx):
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    centre_map(page, *point_at(0, 30))
    for east in (0, 30, 60):
        click_at(page, *point_at(0, east))
    page.wait_for_selector("#planner-error:not([hidden])")
    assert "vertices" in page.locator("#planner-error").inner_text()
    assert page.locator("#waypoint-count").inner_text() == "0"


def test_the_log_viewer_draws_a_dropped_log_and_explains_a_broken_one(
    page, live_asgi, world_tx, tmp_path
):
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/missions/log-viewer/")
    a, b = point_at(0, 0), point_at(0, 30)
    log = {
        "mission": {"name": "two drones", "status": "completed"},
        "drones": [{"id": "A"}, {"id": "B"}],
        "events": [
            {
                "ts": 1.0,
                "type": "step",
                "drone_id": "A",
                "status": "completed",
                "index": 0,
                "position": {"lat": a[0], "lon": a[1]},
                "duration_s": 2,
            },
            {
                "ts": 2.0,
                "type": "step",
                "drone_id": "A",
                "status": "completed",
                "index": 1,
                "position": {"lat": b[0], "lon": b[1]},
                "duration_s": 3,
            },
            {
                "ts": 3.0,
                "type": "alarm",
                "drone_id": "A",
                "message": "CRITICAL",
                "position": {"lat": b[0], "lon": b[1]},
            },
            {
                "ts": 4.0,
                "type": "step",
                "drone_id": "B",
                "status": "completed",
                "index": 2,
                "position": {"lat": a[0], "lon": a[1]},
                "duration_s": 4,
            },
            {
                "ts": 5.0,
                "type": "step",
                "drone_id": "B",
                "status": "completed",
                "index": 3,
                "position": {"lat": b[0], "lon": b[1]},
                "duration_s": 1,
            },
        ],
    }
    good = tmp_path / "mission.json"
    good.write_text(json.dumps(log))
    page.set_input_files("#log-file", str(good))
    page.wait_for_function("window.skyhiveLogViewer.shown !== null")
    shown = page.evaluate("window.skyhiveLogViewer.shown")
    assert shown == {"drones": 2, "marks": 1, "stages": 4}
    assert page.locator("#legend li").count() == 2

    bad = tmp_path / "broken.json"
    bad.write_text('{"mission": {}, "events": [{"ts": "noon"}]}')
    page.set_input_files("#log-file", str(bad))
    page.wait_for_selector("#viewer-error:not([hidden])")
    assert "events[0].ts" in page.locator("#viewer-error").inner_text()


def test_the_panic_page_sends_the_phones_position_and_follows_the_drone(
    browser, live_asgi, world_tx
):
    online_drone(world_tx.org, "ACME_1", north=100)
    caller = point_at(0, 0)
    context = browser.new_context(
        viewport={"width": 390, "height": 800},
        is_mobile=True,
        geolocation={"latitude": caller[0], "longitude": caller[1]},
        permissions=["geolocation"],
        bypass_csp=True,  # wait_for_function evaluates in the page (tests/conftest.py)
    )
    page = context.new_page()
    try:
        login(page, live_asgi, "operator")
        page.goto(f"{live_asgi.url}/missions/panic/")
        page.click("#call-drone")
        page.wait_for_function("document.getElementById('panic-drone').textContent === 'ACME_1'")
        page.wait_for_function("document.getElementById('panic-distance').textContent !== '–'")
        distance = float(page.locator("#panic-distance").inner_text().split()[0])
        assert 95 < distance < 105
        mission = Mission.objects.get()
        navigate = mission.steps.get(command="navigate")
        assert navigate.params["lat"] == pytest.approx(caller[0])
        assert navigate.params["lon"] == pytest.approx(caller[1])
    finally:
        context.close()


def test_the_planner_draws_the_geofence_and_marks_steps_outside_it(page, live_asgi, world_tx):
    from fleet.models import Organisation

    fence = [list(point_at(n, e)) for n, e in ((-30, -30), (-30, 30), (30, 30), (30, -30))]
    Organisation.objects.filter(pk=world_tx.org.pk).update(
        envelope={"geoFence": {"polygons": [{"inclusion": True, "polygon": fence}]}}
    )
    online_drone(world_tx.org, "ACME_1")
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    centre_map(page, *point_at(16, 32))
    page.wait_for_selector("#planner-map path.leaflet-interactive, #planner-map path")
    for lat, lon in rectangle(64.5, 32.5):  # reaches 64 m north, past the 30 m fence
        click_at(page, lat, lon)
    page.wait_for_function("document.getElementById('waypoint-count').textContent !== '0'")
    page.click("#send-mission")
    page.wait_for_selector("#step-list .step.outside-envelope")
    assert "geofence" in page.locator("#planner-error").inner_text()
    assert not Mission.objects.exists()

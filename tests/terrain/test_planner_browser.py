"""The planner in a real browser: a leg refused for its terrain clearance is marked and
drawn, and legs whose clearance cannot be checked are listed before anything is sent."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from fleet import envelopes
from fleet.models import Drone
from missions.models import Mission
from onboard.envelope import ned_to_latlon
from terrain.importer import delete_tiles, import_path
from terrain.models import TerrainTile
from tests.conftest import login

from .dem import HILL_NORTH, HOME, Dem, hill_tile, with_void, write_hgt

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


@contextmanager
def terrain_on_the_server(folder: Path, dem: Dem) -> Iterator[None]:
    """The DEM in the server's own TERRAIN_DIR (the live server is another process)."""
    import_path(write_hgt(folder, dem))
    try:
        yield
    finally:
        delete_tiles(TerrainTile.objects.all())


def plan(page, north: float) -> None:  # type: ignore[no-untyped-def]
    """Take off at home to 50 m and, once there, fly `north` metres (south when negative),
    in the planner."""
    lat, lon = ned_to_latlon(north, 0.0, HOME)
    steps = [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": 50}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": lat, "lon": lon}},
        {"command": "land", "params": {}},
    ]
    page.wait_for_function("window.skyhivePlanner && window.skyhivePlanner.map")
    page.evaluate("(s) => window.skyhivePlanner.steps.push(...s)", steps)
    page.click("#send-mission")


def open_planner(page, live_asgi, world) -> None:  # type: ignore[no-untyped-def]
    envelopes.set_envelope(world.org, {"home": list(HOME)})
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")


def sent(page) -> None:  # type: ignore[no-untyped-def]
    """The mission was created (no drone is online to start it)."""
    try:
        page.wait_for_function(
            "document.querySelector('#planner-error').textContent.includes('draft')"
        )
    except PlaywrightTimeout:
        # What the page said instead, for the failure's report.
        said = page.locator("#planner-error").inner_text()
        raise AssertionError(f"no draft saved; the page says {said!r}") from None
    assert Mission.objects.count() == 1


def test_a_leg_through_the_hill_is_marked_and_drawn(page, live_asgi, world_tx, tmp_path):
    with terrain_on_the_server(tmp_path, hill_tile()):
        open_planner(page, live_asgi, world_tx)
        plan(page, 1.5 * HILL_NORTH)
        page.wait_for_selector("#planner-error:not([hidden])")
        error = page.locator("#planner-error").inner_text()
        assert "Step 3: The straight leg to the target passes" in error
        assert "minimum terrain clearance of 30 m" in error
        page.wait_for_selector("path.offending-leg", state="attached")
        assert page.locator("#terrain-warnings").is_hidden()
        assert not Mission.objects.exists()


def test_a_leg_over_voids_is_listed_and_sent_on_a_second_press(page, live_asgi, world_tx, tmp_path):
    holed = with_void(hill_tile(), *ned_to_latlon(-450.0, 0.0, HOME))
    with terrain_on_the_server(tmp_path, holed):
        open_planner(page, live_asgi, world_tx)
        plan(page, -900.0)
        page.wait_for_selector("#terrain-warnings:not([hidden])")
        assert "(void)" in page.locator("#terrain-warnings li").first.inner_text()
        assert "press Send again" in page.locator("#planner-error").inner_text()
        assert not Mission.objects.exists()
        page.click("#send-mission")
        sent(page)


def test_without_any_terrain_the_planner_says_so_and_sends(page, live_asgi, world_tx):
    open_planner(page, live_asgi, world_tx)
    plan(page, 900.0)
    sent(page)
    assert "No terrain at home" in page.locator("#terrain-warnings li").first.inner_text()


def test_a_terrain_following_survey_is_planned_drawn_and_sent(page, live_asgi, world_tx, tmp_path):
    from .test_following import STRIP

    with terrain_on_the_server(tmp_path, hill_tile()):
        envelopes.set_envelope(world_tx.org, {"home": list(HOME), "max_height": 400, "max_distance": 2000})  # fmt: skip
        login(page, live_asgi, "operator")
        # The envelope (and its home) answers only after the corners are clicked: the
        # heights are still placed above its home, not the first corner's ground.
        held = []

        def hold(route) -> None:  # type: ignore[no-untyped-def]
            if held:
                route.continue_()
            else:
                held.append(route)

        page.route("**/api/v1/organisations/*/envelope/", hold)
        page.goto(f"{live_asgi.url}/missions/plan/")
        page.wait_for_function("window.skyhivePlanner && window.skyhiveAirspace")
        page.check("#follow-terrain")
        page.fill("#altitude", "50")
        page.fill("#step-distance", "300")
        page.evaluate(
            "(pts) => pts.forEach((p) => window.skyhivePlanner.map.fire('click', {latlng: L.latLng(p[0], p[1])}))",
            STRIP,
        )
        # The page asks for the envelope as it loads; its request reaches `hold` as soon
        # as Playwright dispatches events (bound 10 s; the page loads here within 1 s).
        deadline = time.monotonic() + 10.0
        while not held and time.monotonic() < deadline:
            page.wait_for_timeout(20)
        assert len(held) == 1 and page.locator("#height-profile").is_hidden()
        held[0].continue_()
        page.wait_for_selector("#height-profile:not([hidden])")
        summary = page.locator("#height-profile-summary").inner_text()
        assert "above the terrain" in summary, summary
        assert page.locator("polygon.profile-ground").count() >= 1
        speeds = page.evaluate(
            "window.skyhivePlanner.steps.filter((s) => s.command === 'navigate').map((s) => s.params.speed)"
        )
        assert len(speeds) > 4 and all(0 < v <= 5 for v in speeds)
        page.click("#send-mission")
        page.wait_for_selector("#beyond-defaults:not([hidden])")
        page.fill("#beyond-defaults-typed", "CONFIRM")
        page.click("#beyond-defaults-send")
        sent(page)
        mission = Mission.objects.get()
        assert mission.extensibility["terrain_following"]["height_agl_m"] == 50
        assert mission.plan_home == list(HOME)


def test_without_a_home_in_the_envelope_the_heights_stand_on_the_chosen_drone(
    page, live_asgi, world_tx, tmp_path
):
    from .test_following import STRIP

    Drone.objects.filter(drone_id="ACME_1").update(lat=HOME[0], lon=HOME[1])
    with terrain_on_the_server(tmp_path, hill_tile()):
        envelopes.set_envelope(world_tx.org, {"max_height": 400, "max_distance": 2000})
        login(page, live_asgi, "operator")
        # The drones' positions answer only after the corners are clicked.
        held = []

        def hold(route) -> None:  # type: ignore[no-untyped-def]
            held.append(route)

        page.route("**/api/v1/drones/", hold)
        page.goto(f"{live_asgi.url}/missions/plan/")
        page.wait_for_function("window.skyhivePlanner && window.skyhiveAirspace")
        page.select_option("#drone-choice", "ACME_1")
        page.check("#follow-terrain")
        page.fill("#altitude", "50")
        page.fill("#step-distance", "300")
        page.press("#step-distance", "Tab")
        page.evaluate(
            "(pts) => pts.forEach((p) => window.skyhivePlanner.map.fire('click', {latlng: L.latLng(p[0], p[1])}))",
            STRIP,
        )
        deadline = time.monotonic() + 10.0  # asked for as the page loads (within 1 s here)
        while not held and time.monotonic() < deadline:
            page.wait_for_timeout(20)
        assert held and page.locator("#height-profile").is_hidden()
        for route in held:
            route.continue_()
        page.unroute("**/api/v1/drones/", hold)
        page.wait_for_selector("#height-profile:not([hidden])")
        page.click("#send-mission")
        page.wait_for_selector("#beyond-defaults:not([hidden])")
        page.fill("#beyond-defaults-typed", "CONFIRM")
        page.click("#beyond-defaults-send")
        sent(page)
        assert Mission.objects.get().plan_home == list(HOME)

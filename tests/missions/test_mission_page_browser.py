"""In a real browser: a running mission's page shows each drone live on the map with its
progress bar, time left and battery at the end; the step table folds around the current
step; the OpenDroneMap download appears with the first picture, without a reload."""

from __future__ import annotations

import threading
import time

import pytest
from django.utils import timezone

from fleet.heartbeats import handle_heartbeat
from fleet.models import Drone
from missions.models import Assignment, Mission, Step, StepStatus
from onboard.protocol import Heartbeat, MissionRef, Position
from tests.conftest import login
from tests.support.screenshots import docs_screenshot

from .test_mission_page import north
from .test_pictures import store_sample_picture

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

STEPS = 30


def running_mission(world) -> Mission:  # type: ignore[no-untyped-def]
    """30 waypoints 20 m apart northwards; ACME_1 has done the first 12."""
    mission = Mission.objects.create(organisation=world.org, name="survey", status="running")
    for index in range(STEPS):
        lat, lon = north(index * 20)
        done = index < 12
        Step.objects.create(
            mission=mission,
            index=index,
            command="navigate",
            params={"lat": lat, "lon": lon},
            status=StepStatus.COMPLETED if done else StepStatus.PENDING,
            drone=world.drone if done else None,
            position={"lat": lat, "lon": lon, "alt": 15} if done else None,
            ended_at=timezone.now() if done else None,
        )
    Assignment.objects.create(
        mission=mission,
        drone=world.drone,
        step_indexes=list(range(STEPS)),
        status=Assignment.Status.ACCEPTED,
    )
    lat, lon = north(11 * 20)
    Drone.objects.filter(pk=world.drone.pk).update(
        online=True, airborne=True, armed=True, lat=lat, lon=lon, alt=15, battery_remaining=0.8,
        home=list(north(0)), last_seen=timezone.now(),
    )  # fmt: skip
    return mission


def beat(mission: Mission, metres: float, remaining: float) -> Heartbeat:
    lat, lon = north(metres)
    return Heartbeat(
        drone_id="ACME_1",
        ts=time.time(),
        position=Position(lat=lat, lon=lon, alt=15.0),
        battery_voltage=15.5,
        battery_remaining=remaining,
        armed=True,
        airborne=True,
        flight_mode="PositionHold",
        mission=MissionRef(mission_id=str(mission.pk), assignment_id=None, index=12),
        fc_protocol="uavtalk",
        fc_connected=True,
    )


def test_the_mission_page_shows_live_progress_and_folds_the_steps(page, live_asgi, world_tx):
    mission = running_mission(world_tx)
    corners = [north(-50), north(700), [north(700)[0], -7.99], [north(-50)[0], -7.99]]
    world_tx.org.envelope = {
        "geoFence": {
            "version": 2,
            "polygons": [{"inclusion": True, "polygon": corners, "version": 1}],
            "circles": [
                {"inclusion": False, "circle": {"center": north(300), "radius": 20}, "version": 1}
            ],
        }
    }
    world_tx.org.save()
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
    page.wait_for_selector("#live-status.ok")
    item = page.locator(".progress-item[data-drone='ACME_1']")
    item.locator(".progress-bar").wait_for(timeout=10_000)
    assert "12 / 30 steps" in item.inner_text()
    assert item.locator(".progress-bar").get_attribute("aria-valuenow") == "12"
    # 18 waypoints left, 20 m apart, from the 11th: 360 m at the default 5 m/s.
    first = page.evaluate("skyhiveMission.progress('ACME_1')")
    assert first["remaining_m"] == pytest.approx(360, rel=0.01)
    assert first["time_remaining_s"] == pytest.approx(72, rel=0.01)
    assert page.evaluate("skyhiveMission.dronePosition('ACME_1')") is not None
    assert page.evaluate("skyhiveMission.droneState('ACME_1')") == "airborne"
    # The geofence: the inclusion polygon and the exclusion circle, and the drone's home.
    assert page.evaluate("skyhiveMission.fenceShapes()") == 2
    assert page.locator("#mission-map .home-marker").count() == 1

    # Steps: the current one (12) with two before and five after; the rest folded.
    page.wait_for_selector("#step-table tr.step-current[data-index='12']")
    shown = page.eval_on_selector_all(
        "#step-table tr[data-index]", "rs => rs.map(r => +r.dataset.index)"
    )
    assert shown == list(range(10, 18))
    assert page.locator("#step-table tr.step-gap").count() == 2
    page.click("#steps-toggle")
    assert page.locator("#step-table tr[data-index]").count() == STEPS

    # The drone flies on: live heartbeats move its icon and shorten what is left; the
    # drain measured between them gives the battery at the end.
    assert handle_heartbeat("ACME_1", beat(mission, 11 * 20 + 10, 0.80)) is None
    page.wait_for_function("skyhiveMission.progress('ACME_1').remaining_m < 355", timeout=10_000)
    time.sleep(11)  # the drain is measured over at least ten seconds
    assert handle_heartbeat("ACME_1", beat(mission, 11 * 20 + 15, 0.79)) is None
    page.wait_for_function(
        "skyhiveMission.progress('ACME_1').battery_at_end !== null", timeout=10_000
    )
    progress = page.evaluate("skyhiveMission.progress('ACME_1')")
    assert progress["remaining_m"] == pytest.approx(5 + 17 * 20, rel=0.01)  # to step 12, on
    assert progress["battery_at_end"] < 0.79
    assert "at the end" in item.inner_text() and "reserve" in item.inner_text()
    assert page.evaluate("performance.getEntriesByType('navigation').length") == 1

    # The first picture: the ZIP download appears without a reload.
    assert page.locator("#odm-links").is_hidden()
    stored = []
    worker = threading.Thread(
        target=lambda: stored.append(store_sample_picture(world_tx.drone, mission, 12))
    )  # the channel layer's synchronous send cannot run beside Playwright's event loop
    worker.start()
    worker.join()
    assert stored == [None]
    page.locator("#odm-zip").wait_for(state="visible", timeout=10_000)
    docs_screenshot(page, "mission")


def test_the_progress_bar_fits_a_phone(browser, live_asgi, world_tx):
    mission = running_mission(world_tx)
    context = browser.new_context(viewport={"width": 390, "height": 844}, is_mobile=True)
    page = context.new_page()
    try:
        login(page, live_asgi, "viewer")
        page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
        bar = page.locator(".progress-item[data-drone='ACME_1'] .progress-bar")
        bar.wait_for(timeout=10_000)
        box = bar.bounding_box()
        assert box["width"] > 200 and box["x"] + box["width"] <= 390
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    finally:
        context.close()

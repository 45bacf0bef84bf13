"""In a real browser at 1280 and 390 px: the fleet map's markers by state, the table that
fits, live changes from real heartbeats without a reload, and a drone page's command
history and clock kept current."""

from __future__ import annotations

import time

import pytest
from django.utils import timezone

from fleet.heartbeats import handle_heartbeat
from fleet.models import CommandLog, Drone
from onboard.protocol import Heartbeat, MissionRef, Position
from tests.conftest import login
from tests.support.screenshots import docs_screenshot

from .test_fleet_page import FLEET, make_fleet

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

EXPECTED_STATES = {
    "GROUND_1": "on_ground",
    "ARMED_1": "armed",
    "AIR_1": "airborne",
    "HOME_1": "returning",
    "LOW_1": "low_battery",
    "LOST_1": "lost_link",
}


def heartbeat(drone_id: str, *, lat: float, alt: float, ts: float | None = None) -> Heartbeat:
    return Heartbeat(
        drone_id=drone_id,
        ts=time.time() if ts is None else ts,
        position=Position(lat=lat, lon=-8.0, alt=alt),
        battery_voltage=15.8,
        battery_remaining=0.77,
        armed=True,
        airborne=True,
        flight_mode="PositionHold",
        mission=MissionRef(mission_id="survey", assignment_id=None, index=4),
        fc_protocol="uavtalk",
        fc_connected=True,
    )


def no_horizontal_scroll(page) -> bool:  # type: ignore[no-untyped-def]
    return page.evaluate(
        "document.documentElement.scrollWidth <= window.innerWidth"
        " && document.querySelector('.fleet-table-wrap').scrollWidth"
        " <= document.querySelector('.fleet-table-wrap').clientWidth + 1"
    )


def open_fleet(page, live_asgi, markers: int) -> None:  # type: ignore[no-untyped-def]
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    page.wait_for_selector("#live-status.ok")
    page.wait_for_function(f"window.skyhiveFleet.markerIds().length === {markers}", timeout=10_000)
    page.wait_for_selector("#drone-table tbody tr[data-drone='LOW_1']")


def test_markers_and_rows_show_each_state_and_follow_a_heartbeat(page, live_asgi, world_tx):
    make_fleet(world_tx.org)
    Drone.objects.filter(drone_id="ACME_1").update(lat=40.01, lon=-8.0)
    open_fleet(page, live_asgi, 7)

    for drone_id, state in EXPECTED_STATES.items():
        assert page.evaluate(f"skyhiveFleet.markerState('{drone_id}')") == state, drone_id
        row = page.locator(f"#drone-table tr[data-drone='{drone_id}']")
        assert row.get_attribute("data-state") == state
    low = page.locator("#drone-table tr[data-drone='LOW_1']")
    assert low.locator("[data-field=state]").inner_text() == "low battery"
    assert low.locator("[data-field=alt]").inner_text() == "12.5 m"
    assert "m1" in low.locator("[data-field=mission]").inner_text()
    assert "· 13 m" in page.evaluate("skyhiveFleet.markerHtml('LOW_1')")  # altitude label
    assert no_horizontal_scroll(page), "the table fits at 1280 px"

    # A real heartbeat (the gateway's own handler): GROUND_1 takes off and flies north.
    assert handle_heartbeat("GROUND_1", heartbeat("GROUND_1", lat=40.0, alt=20.0)) is None
    row = page.locator("#drone-table tr[data-drone='GROUND_1']")
    page.wait_for_function("skyhiveFleet.markerState('GROUND_1') === 'airborne'", timeout=10_000)
    assert row.get_attribute("data-state") == "airborne"
    assert row.locator("[data-field=alt]").inner_text() == "20.0 m"
    assert "77 %" in row.locator("[data-field=battery]").inner_text()
    assert "survey" in row.locator("[data-field=mission]").inner_text()
    time.sleep(1.2)  # past the live-update throttle
    assert handle_heartbeat("GROUND_1", heartbeat("GROUND_1", lat=40.0002, alt=21.0)) is None
    page.wait_for_function("skyhiveFleet.markerPosition('GROUND_1').lat > 40.0001", timeout=10_000)
    # About 22 m north in about 1.2 s: a speed, a northern heading, an arrow on the marker.
    assert row.locator("[data-field=speed]").inner_text().endswith("m/s")
    assert row.locator("[data-field=heading]").inner_text().endswith(" N")
    assert 'class="arrow"' in page.evaluate("skyhiveFleet.markerHtml('GROUND_1')")
    assert page.evaluate("performance.getEntriesByType('navigation').length") == 1  # no reload
    docs_screenshot(page, "fleet")


def test_the_table_collapses_into_cards_on_a_phone(browser, live_asgi, world_tx):
    make_fleet(world_tx.org)
    context = browser.new_context(
        viewport={"width": 390, "height": 844},
        is_mobile=True,
        # wait_for_function polls with eval in the page once its first try finds the
        # markers not yet drawn, which the policy refuses (tests/conftest.py)
        bypass_csp=True,
    )
    page = context.new_page()
    try:
        open_fleet(page, live_asgi, 6)
        assert no_horizontal_scroll(page)
        assert page.locator("#drone-table thead").is_hidden()
        cell = page.locator("#drone-table tr[data-drone='AIR_1'] [data-field=battery]")
        label = cell.evaluate("el => getComputedStyle(el, '::before').content")
        assert label == '"Battery"'
        assert page.locator("#fleet-map").bounding_box()["width"] <= 390
    finally:
        context.close()


def test_the_drone_page_follows_commands_and_the_clock_live(page, live_asgi, world_tx):
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.wait_for_function("document.querySelector('#command-history .empty')")
    # The snapshot is sent once the socket joined its group: changes from now on reach it.
    page.wait_for_function("performance.getEntriesByName('fleet:snapshot').length > 0")

    entry = CommandLog.objects.create(
        drone=world_tx.drone, user=world_tx.operator, request_id="r1", command="takepic"
    )
    item = page.locator(f"#command-history [data-command-id='{entry.pk}']")
    item.wait_for(timeout=10_000)
    assert "takepic — Pending by operator" in item.inner_text()
    entry.outcome = CommandLog.Outcome.OK
    entry.save(update_fields=["outcome"])
    page.wait_for_function(
        f"document.querySelector(\"[data-command-id='{entry.pk}']\").dataset.outcome === 'ok'",
        timeout=10_000,
    )
    assert page.locator("#command-history .empty").count() == 0

    # A drone whose clock is 30 s behind the ground's: the Clock row says so, live.
    late = heartbeat("ACME_1", lat=40.0, alt=5.0, ts=time.time() - 30)
    assert handle_heartbeat("ACME_1", late) is None
    clock = page.locator("#drone-status [data-field=clock]")
    page.wait_for_function(
        "document.querySelector('#drone-status [data-field=clock]').textContent"
        ".includes('not trusted')",
        timeout=10_000,
    )
    assert clock.inner_text().startswith("-30")
    assert page.locator("#drone-status [data-field=state]").inner_text() == "airborne"
    assert page.locator("#drone-status [data-field=alt]").inner_text() == "5.0 m"
    assert len(FLEET) == 6


def big_fleet(org, count: int) -> None:  # type: ignore[no-untyped-def]
    """`count` drones over a few kilometres, each fifth low on battery, each third lost."""
    now = timezone.now()
    Drone.objects.bulk_create(
        [
            Drone(
                organisation=org,
                drone_id=f"SWARM_{i:05d}",
                online=i % 3 != 0,
                airborne=i % 2 == 0,
                armed=i % 2 == 0,
                battery_remaining=0.1 if i % 5 == 0 else 0.9,
                lat=40.60 + (i % 50) * 0.001,
                lon=-8.70 + (i // 50) * 0.001,
                alt=10.0,
                last_seen=now,
                mission={"mission_id": "m", "index": 1} if i % 7 == 0 else None,
            )
            for i in range(count)
        ]
    )


def test_two_thousand_drones_cluster_and_page_with_search_and_filters(page, live_asgi, world_tx):
    big_fleet(world_tx.org, 2000)
    login(page, live_asgi, "viewer")
    sockets: list[str] = []
    page.on("websocket", lambda socket: sockets.append(socket.url))
    page.goto(f"{live_asgi.url}/")
    page.wait_for_function("document.documentElement.dataset.fleetReady", timeout=30_000)
    assert page.evaluate("skyhiveFleet.markerIds().length") == 2000
    # Clustered: a few hundred markers at most on the map, not 2 000.
    assert 0 < page.evaluate("skyhiveFleet.shownMarkers()") < 300
    # The socket the page's head opened early is the one the map listens on.
    assert len([url for url in sockets if "/ws/fleet/" in url]) == 1
    assert page.evaluate("skyhiveFleet.markerState('SWARM_00003')") == "lost_link"
    assert page.evaluate("skyhiveFleet.markerState('SWARM_00004')") == "airborne"
    # The first draw's partial index is followed by the full one, for every zoom.
    page.wait_for_function("skyhiveFleet.clusterZoom() === 15", timeout=10_000)
    assert 0 < page.evaluate("skyhiveFleet.shownMarkers()") < 300
    page.evaluate("skyhiveFleet.map.setZoom(17, { animate: false })")
    page.wait_for_function("document.querySelectorAll('.drone-marker').length > 0")
    assert page.locator(".drone-cluster").count() == 0
    assert page.locator("#drone-table tbody tr").count() == 50
    count = page.locator("#fleet-count")
    assert count.inner_text() == "2001 drones"  # and ACME_1

    def expect(text: str) -> None:
        page.wait_for_function(
            f"document.getElementById('fleet-count').textContent === '{text}'", timeout=10_000
        )

    page.fill("#fleet-search", "SWARM_0199")
    expect("10 drones")
    page.fill("#fleet-search", "SWARM_01999")
    expect("1 drone")
    assert page.locator("#drone-table tbody tr").get_attribute("data-drone") == "SWARM_01999"
    page.fill("#fleet-search", "")
    expect("2001 drones")

    lost = Drone.objects.filter(organisation=world_tx.org, online=False).count()
    page.check("input[name=filter][value=lost_link]")
    expect(f"{lost} drones")
    rows = page.eval_on_selector_all("#drone-table tbody tr", "rs => rs.map(r => r.dataset.state)")
    assert set(rows) == {"lost_link"}
    page.uncheck("input[name=filter][value=lost_link]")
    page.check("input[name=filter][value=low_battery]")
    page.check("input[name=filter][value=airborne]")
    low_flying = Drone.objects.filter(
        organisation=world_tx.org, online=True, airborne=True, battery_remaining__lte=0.25
    ).count()
    expect(f"{low_flying} drones")
    page.uncheck("input[name=filter][value=airborne]")
    page.uncheck("input[name=filter][value=low_battery]")
    page.check("input[name=filter][value=mission]")
    expect(f"{Drone.objects.filter(mission__isnull=False).count()} drones")
    page.uncheck("input[name=filter][value=mission]")
    expect("2001 drones")
    page.click("#page-next")
    page.wait_for_selector("#drone-table tbody tr[data-drone='SWARM_00049']")
    assert page.locator("#page-info").inner_text() == "page 2 of 41"

    # The shared drone picker (here the missions list's drone filter) asks the same API.
    page.goto(f"{live_asgi.url}/missions/")
    page.fill("input[name=drone]", "SWARM_0001")
    page.wait_for_function(
        "document.querySelector('input[name=drone]').dataset.matches === '10'", timeout=10_000
    )
    options = page.eval_on_selector_all(
        "input[name=drone] + datalist option", "os => os.map(o => o.value)"
    )
    assert options == [f"SWARM_{i:05d}" for i in range(10, 20)]


def test_the_telemetry_overview_follows_its_drones_live(page, live_asgi, world_tx):
    make_fleet(world_tx.org)
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/telemetry/?filter=lost_link")
    row = page.locator("#telemetry-overview tr[data-drone='LOST_1']")
    assert row.locator("[data-field=online]").inner_text() == "offline"
    # The snapshot is sent once the socket joined its group: changes from now on reach it.
    page.wait_for_function("performance.getEntriesByName('fleet:snapshot').length > 0")
    assert handle_heartbeat("LOST_1", heartbeat("LOST_1", lat=40.0, alt=3.0)) is None
    page.wait_for_function(
        "document.querySelector('tr[data-drone=LOST_1] [data-field=online]')"
        ".textContent === 'online'",
        timeout=10_000,
    )
    assert row.locator("[data-field=battery]").inner_text().strip() == "77 %"

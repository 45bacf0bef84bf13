"""The dashboard in a real browser: live charts move as a drone publishes, history loads."""

from __future__ import annotations

import threading
import time

import pytest

from telemetry.ingest import CounterSink, DroneMap, IngestConfig, Ingestor, load_drone_ids
from telemetry.live import ChannelsLivePublisher
from telemetry.queries import conninfo_from_settings
from tests.conftest import login
from workers.mosquitto import start_broker

from .support import Publisher, drone_messages

pytestmark = [pytest.mark.browser, pytest.mark.e2e]


@pytest.fixture
def flying(world_tx, tmp_path):
    """ACME_1 publishing its telemetry in real time through a broker and the ingest."""
    broker = start_broker(tmp_path, {"ground": "g", "ACME_1": "a"})
    conninfo = conninfo_from_settings()
    ingestor = Ingestor(
        IngestConfig(conninfo=conninfo, mqtt_url=broker.url_for("ground")),
        drones=DroneMap(lambda: load_drone_ids(conninfo)),
        counters=CounterSink(),
        live=ChannelsLivePublisher(refresh_every=0.2),
    )
    ingestor.start()
    stop = threading.Event()

    def fly() -> None:
        drone = Publisher(broker.url_for("ACME_1"))
        while not stop.is_set():
            for message in drone_messages(time.time(), seconds=1):
                drone.publish("ACME_1/telemetry/out", message, qos=0)
                if stop.wait(0.1):
                    break
        drone.close()

    pilot = threading.Thread(target=fly, daemon=True)
    pilot.start()
    yield ingestor
    stop.set()
    pilot.join(5)
    ingestor.stop(drain_timeout=5)
    broker.stop()


def _points(page, panel: str) -> int:
    return int(page.get_attribute(f"[data-panel={panel}]", "data-points") or 0)


def test_the_dashboard_charts_move_live_and_load_history(page, live_asgi, flying):
    login(page, live_asgi, "owner")
    page.goto(f"{live_asgi.url}/telemetry/drones/ACME_1/")
    assert page.locator("[data-panel]").count() == 8
    page.wait_for_function(
        "document.querySelector('[data-panel=barometer]').dataset.points >= 2", timeout=15000
    )
    before = _points(page, "barometer")
    page.wait_for_function(
        f"document.querySelector('[data-panel=barometer]').dataset.points > {before}",
        timeout=10000,
    )
    assert page.locator("[data-stat='FlightBatteryState.Voltage']").inner_text().endswith(" V")
    assert page.locator("[data-stat='FlightStatus.FlightMode']").inner_text() == "PathPlanner"

    page.click("[data-range='900']")
    page.wait_for_function(
        "document.getElementById('tm-state').textContent.includes('loaded in')", timeout=10000
    )
    assert _points(page, "gyros") > 0
    assert page.get_attribute("[data-range='900']", "aria-pressed") == "true"

    page.goto(f"{live_asgi.url}/telemetry/")
    row = page.locator("tr[data-drone=ACME_1]")
    assert " V" in row.inner_text()
    assert "Connected" in row.inner_text()
    assert "GLOBEX_1" not in page.content()


def test_the_dashboard_fits_a_phone_screen(browser, live_asgi, world_tx):
    context = browser.new_context(viewport={"width": 390, "height": 800}, is_mobile=True)
    page = context.new_page()
    try:
        login(page, live_asgi, "owner")
        page.goto(f"{live_asgi.url}/telemetry/drones/ACME_1/")
        page.wait_for_selector("[data-panel=altitude] canvas")
        assert page.evaluate("document.documentElement.scrollWidth") <= 390
    finally:
        context.close()

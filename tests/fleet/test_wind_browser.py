"""The drone page's wind card in a real browser: the wind its flight controller
estimated against the gear's limit, kept current from the drone's heartbeats."""

from __future__ import annotations

import time
from dataclasses import replace

import pytest

from fleet.heartbeats import handle_heartbeat
from fleet.models import Drone
from onboard.protocol import WindReport
from tests.conftest import login
from tests.fleet.test_fleet_page_browser import heartbeat

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_the_drone_page_shows_the_wind_against_the_limit_live(page, live_asgi, world_tx, settings):
    settings.FLEET_PUSH_INTERVAL_S = 0.0  # every heartbeat reaches the page
    Drone.objects.filter(drone_id="ACME_1").update(
        specs={"MAX_WIND_M_S": 8},
        airborne=False,
        fc={"protocol": "mavlink", "wind": {"north": 0.0, "east": 5.0, "down": 0.0,
                                            "speed": 5.0, "limit": 8.0, "source": "WIND"}},
    )  # fmt: skip
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    card = page.locator("#wind")
    assert "5.0 m/s from 270°" in card.inner_text()
    assert "8 m/s" in card.locator("[data-wind=limit]").inner_text()
    assert card.locator("[data-wind=verdict]").get_attribute("data-above") == "no"
    # The snapshot is sent once the socket joined its group: changes from now on reach it.
    page.wait_for_function("performance.getEntriesByName('fleet:snapshot').length > 0")

    # The wind rises to 12 m/s from the north, then the drone returns: live.
    beat = heartbeat("ACME_1", lat=40.0, alt=10.0)
    wind = WindReport(north=-12.0, east=0.0, down=0.0, speed=12.0, limit=8.0, source="WIND_COV")
    assert handle_heartbeat("ACME_1", replace(beat, wind=wind)) is None
    page.wait_for_function(
        "document.querySelector('#wind [data-wind=verdict]').dataset.above === 'yes'",
        timeout=10_000,
    )
    assert "12.0 m/s from 0°" in card.inner_text()
    assert "WIND_COV" in card.inner_text()
    returning = replace(wind, action="return", since=time.time())
    assert handle_heartbeat("ACME_1", replace(heartbeat("ACME_1", lat=40.0, alt=10.0),
                                              wind=returning)) is None  # fmt: skip
    page.wait_for_function(
        "document.querySelector('#wind [data-wind=verdict]').textContent.includes('returning')",
        timeout=10_000,
    )


def test_a_drone_whose_flight_controller_gives_no_wind_says_so(page, live_asgi, world_tx):
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    card = page.locator("#wind")
    assert "not estimated by its flight controller" in card.inner_text()
    assert "10 m/s" in card.locator("[data-wind=limit]").inner_text()

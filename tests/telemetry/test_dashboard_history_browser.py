"""A dashboard opened while nothing is live starts with the last minutes of stored history
and labels its time axis HH:MM:SS in local time."""

from __future__ import annotations

import re
import time

import pytest

from telemetry.storage import Sample
from tests.conftest import login
from tests.telemetry.test_api import _store

pytestmark = [pytest.mark.browser]


def test_live_charts_open_with_the_last_minutes_and_readable_times(page, live_asgi, world_tx):
    now = time.time()
    pk = world_tx.drone.pk
    _store(
        [
            Sample(now - 240 + i, pk, "BaroAltitude", {"Pressure": 101.0 + i / 1000})
            for i in range(230)
        ]
        + [Sample(now - 3600, pk, "BaroAltitude", {"Pressure": 90.0})]  # an hour ago: not shown
    )
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/telemetry/drones/ACME_1/")
    root = page.locator("#telemetry-dashboard")
    page.wait_for_function("document.getElementById('telemetry-dashboard').dataset.prefilled")
    page.wait_for_function("document.querySelector('[data-panel=barometer]').dataset.points > 100")
    # Live, only the snapshot of the latest values came: the hundred points are history.
    assert root.get_attribute("data-updates") in (None, "1")
    chart = "window.telemetryCharts[0].plot"
    values = page.evaluate(f"{chart}.data[1].filter((v) => v != null)")
    assert min(values) > 100  # the sample of an hour ago is outside the live window
    ticks = page.evaluate(f"{chart}.axes[0]._values")
    assert ticks and all(re.fullmatch(r"\d\d:\d\d:\d\d", t) for t in ticks), ticks
    battery = "window.telemetryCharts.find((c) => c.panel.id === 'battery').plot"
    axes = page.evaluate(f"{battery}.axes.slice(1).map((a) => [a.scale, a.label])")
    assert axes == [["V", "V"], ["A", "A"]]  # volts and amps each on their own axis
    href = page.get_attribute("#tm-export-long", "href")
    assert "layout=long" in href and "layout" not in page.get_attribute("#tm-export", "href")

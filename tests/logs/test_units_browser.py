"""The log viewer shows a real PX4 log in display units, each unit on its own y axis, and
on request every line normalised to one shared axis."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from playwright.sync_api import expect

from tests.conftest import login
from tests.logs.conftest import upload, wait_until_processed
from tests.logs.test_api import client_for
from tests.support.screenshots import docs_screenshot

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]

ULOG = Path(__file__).resolve().parents[1] / "data" / "ulog" / "sample_log_small.ulg"
VOLTS, ALTITUDE = "battery_status_0/voltage_v", "vehicle_gps_position/alt"


def test_the_viewer_labels_units_and_gives_each_its_own_axis(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    created = upload(client, shutil.copy(ULOG, tmp_path / "flight.ulg")).json()
    assert wait_until_processed(client, created["id"])["status"] == "ready"
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")
    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)

    picker = viewer.locator('[data-part="picker"]')
    assert picker.locator(f'label:has(input[value="{VOLTS}"]) .unit').inner_text() == "V"
    assert picker.locator(f'label:has(input[value="{ALTITUDE}"]) .unit').inner_text() == "m"
    remaining = 'label:has(input[value="battery_status_0/remaining"]) .unit'
    assert picker.locator(remaining).inner_text() == "%"

    page.evaluate(f"window.logViewers[0].setPlotPaths(['{VOLTS}', '{ALTITUDE}'])")
    chart = "window.logViewers[0].multi.u"
    page.wait_for_function(
        f"{chart}.data.length === 3 && [1, 2].every((i) => {chart}.data[i].some((v) => v != null))"
    )
    axes = page.evaluate(f"{chart}.axes.slice(1).map((a) => [a.scale, a.label, a.side])")
    assert axes == [["unit:V", "V", 3], ["unit:m", "m", 1]]
    volts = page.evaluate(f"{chart}.data[1].filter((v) => v != null)")
    metres = page.evaluate(f"{chart}.data[2].filter((v) => v != null)")
    assert 10 < min(volts) <= max(volts) < 30  # a 4-cell pack, in volts
    assert max(abs(m) for m in metres) < 10_000  # metres above the ellipsoid, not millimetres
    legend = viewer.locator('[data-part="multi"] .u-legend').inner_text()
    assert "[V]" in legend and "[m]" in legend
    docs_screenshot(page, "log-viewer", height=1000)

    viewer.locator('[data-part="normalise"]').check()
    page.wait_for_function(f"{chart}.axes.length === 2")
    assert page.evaluate(f"{chart}.axes[1].label") == "0–1"
    values = page.evaluate(f"{chart}.data.slice(1).flat().filter((v) => v != null)")
    assert min(values) == 0 and max(values) == 1

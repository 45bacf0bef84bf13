"""The health report on a log's page in headless Chromium: first panel, coloured status per
check, a finding's link moving the viewer to its moment and plot, and the spectrum."""

from __future__ import annotations

import re

import pytest
from playwright.sync_api import expect

from logs.synth_faults import FAULT_AT, px4_ulog
from tests.conftest import login
from tests.logs.conftest import upload, wait_until_processed
from tests.logs.test_api import client_for

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]


def test_the_health_report_leads_the_page_and_its_links_open_the_finding(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    created = upload(client, px4_ulog(tmp_path / "sagging.ulg", {"battery"})).json()
    assert wait_until_processed(client, created["id"])["status"] == "ready"
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")

    viewer = page.locator("[data-log-viewer]")
    health = viewer.locator('[data-part="health"]')
    expect(health).to_have_attribute("data-loaded", "true", timeout=15_000)
    # The report is the first thing in the viewer's body, above the replay toolbar.
    first = viewer.locator('[data-part="body"] > *').first
    expect(first).to_have_attribute("data-part", "health")
    rows = health.locator("[data-check]")
    expect(rows).to_have_count(10)
    # Failures first, coloured; the rest pass.
    expect(rows.first).to_have_attribute("data-check", "battery_sag")
    expect(rows.first).to_have_class("lv-check bad")
    expect(rows.first.locator(".badge")).to_have_text("fail")
    expect(health.locator('[data-status="pass"]')).to_have_count(9)
    expect(health.locator('[data-part="health-summary"]')).to_have_text("1 failed · 9 passed")

    rows.first.locator("[data-check-link]").click()
    expect(viewer.locator('[data-part="clock"]')).to_have_text("t = 00:45.000")
    lines = viewer.locator('[data-part="lines"] tbody tr')
    expect(lines.first).to_have_attribute("data-path", "battery_status/voltage_v")
    view = page.evaluate("window.logViewers[0].state.view")
    start = page.evaluate("window.logViewers[0].state.start")
    assert view[0] - start < FAULT_AT["battery"] < view[1] - start

    viewer.locator('[data-action="spectrum"]').click()
    card = viewer.locator('[data-part="spectrum-card"]')
    expect(card).to_have_attribute("data-loaded", "true", timeout=10_000)
    expect(card.locator("canvas")).to_have_count(1)
    expect(card.locator('[data-part="spectrum-note"]')).to_contain_text("10 Hz")
    # The address keeps the spectrum open: a shared link shows it again.
    expect(page).to_have_url(re.compile(r"spec=1"))
    page.reload()
    card = page.locator('[data-log-viewer] [data-part="spectrum-card"]')
    expect(card).to_have_attribute("data-loaded", "true", timeout=15_000)
    if shots := __import__("os").environ.get("LOGS_SCREENSHOTS"):
        page.screenshot(path=f"{shots}/health.png", full_page=True)


# A machine ten times slower, as far as the page can tell: every timer waits ten times its
# delay and the plots' data comes 5 s late, so the operator acts long before the viewer
# has finished loading.
SLOW_MACHINE = """
const realTimeout = window.setTimeout;
window.setTimeout = (fn, ms, ...rest) => realTimeout(fn, (ms || 0) * 10, ...rest);
const realFetch = window.fetch;
window.fetch = async (url, options) => {
  if (String(url).includes("/series/")) await new Promise((done) => realTimeout(done, 5000));
  return realFetch(url, options);
};
"""


def test_the_address_follows_what_the_operator_opens_before_the_viewer_has_loaded(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    created = upload(client, px4_ulog(tmp_path / "sagging.ulg", {"battery"})).json()
    assert wait_until_processed(client, created["id"])["status"] == "ready"
    page.add_init_script(SLOW_MACHINE)
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")

    viewer = page.locator("[data-log-viewer]")
    health = viewer.locator('[data-part="health"]')
    expect(health).to_have_attribute("data-loaded", "true", timeout=15_000)
    health.locator("[data-check-link]").first.click()
    expect(viewer.locator('[data-part="clock"]')).to_have_text("t = 00:45.000")
    viewer.locator('[data-action="spectrum"]').click()
    assert viewer.get_attribute("data-loaded") is None  # still loading: the premise
    # The address is written 300 ms (here 3 s) after the last change.
    expect(page).to_have_url(re.compile(r"t=45&.*plot=battery_status.*&spec=1"), timeout=15_000)

"""The fleet's trend page and two logs on one time axis, in headless Chromium (the pages'
scripts run under the site's CSP: no inline script or style)."""

from __future__ import annotations

from datetime import timedelta

import pytest
from playwright.sync_api import expect

from logs.synth_faults import px4_ulog
from tests.conftest import login
from tests.logs.test_log_parameters import PX4_A, PX4_B
from tests.logs.test_trends import DAY0, TOPICS, imported

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]


def test_overlay_of_two_logs_and_their_parameters(world_tx, live_logs, page, tmp_path):
    a = imported(world_tx.org, px4_ulog(tmp_path / "a.ulg", seconds=15.0, parameters=PX4_A))
    b = imported(world_tx.org, px4_ulog(tmp_path / "b.ulg", seconds=20.0, parameters=PX4_B))
    errors: list[str] = []
    # Errors thrown by the Logs pages' own scripts (the shared header's are not ours).
    page.on("pageerror", lambda exc: "/js/logs/" in (exc.stack or "") and errors.append(exc.stack))
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/compare/?ids={a.pk},{b.pk}")
    page.locator("#overlay-link").click()

    expect(page.locator("#overlay-takeoff")).to_contain_text("A took off at 5.00 s (arming)")
    plot = page.locator("#overlay-plot")
    expect(plot).to_have_attribute("data-series", "2", timeout=15_000)
    expect(plot.locator("canvas")).to_have_count(1)
    assert (
        page.locator("#overlay-path").input_value() == "vehicle_imu_status/accel_vibration_metric"
    )

    page.locator("#overlay-align").select_option("start")
    page.locator("#overlay-offset").fill("2.5")
    page.locator("#overlay-offset").dispatch_event("change")
    expect(plot.locator(".u-legend")).to_contain_text("s since start")

    # Two plots asked for one after the other, the first one's answers coming last:
    # the newest is what stays drawn.
    held = []

    def hold_first_two(route) -> None:  # type: ignore[no-untyped-def]
        if len(held) < 2:
            held.append(route)
        else:
            route.continue_()

    page.route("**/series/?*", hold_first_two)
    page.locator("#overlay-align").select_option("takeoff")
    page.locator("#overlay-align").select_option("start")
    expect(plot.locator(".u-legend")).to_contain_text("s since start")
    drawn_from = plot.get_attribute("data-from")  # the plot's first time, since the start
    assert len(held) == 2
    for route in held:
        route.continue_()
    page.unroute("**/series/?*", hold_first_two)
    page.wait_for_timeout(500)  # the late answers arrive and would be drawn (well within)
    assert plot.get_attribute("data-from") == drawn_from

    page.get_by_role("button", name="A against B").click()
    rows = page.locator("#param-diff tbody tr")
    expect(rows).to_have_count(3)
    expect(page.locator('#param-diff tr[data-change="changed"]')).to_contain_text("MC_ROLL_P")
    expect(page.locator("#param-summary")).to_contain_text("3 differ, 2 the same")
    # A viewer may not save a reference: no button; none saved yet says so.
    expect(page.locator("#save-reference")).to_have_count(0)
    page.get_by_role("button", name="A against its model's reference").click()
    expect(page.locator("#param-summary")).to_contain_text("No reference parameter set")
    assert not errors, errors


def test_naming_the_drone_of_a_log_puts_it_in_the_fleet_trend_which_marks_the_drift(
    world_tx, live_logs, page, tmp_path
):
    levels = [2.0, 2.05, 2.1, 2.1, 2.15, 3.2]
    for i, level in enumerate(levels[:-1]):
        path = px4_ulog(tmp_path / f"{i}.ulg", vibration=level, seconds=15.0, topics=TOPICS)
        imported(world_tx.org, path, drone=world_tx.drone, flown_at=DAY0 + timedelta(days=i))
    # The last flight was uploaded by hand: its operator names the drone on its page.
    last = imported(
        world_tx.org,
        px4_ulog(tmp_path / "5.ulg", vibration=levels[-1], seconds=15.0, topics=TOPICS),
    )
    login(page, live_logs, "operator")
    page.goto(f"{live_logs.url}/logs/{last.pk}/")
    page.locator("#drone-tie select").select_option("ACME_1")
    page.locator("#drone-tie button").click()
    expect(page.locator("#log-drone")).to_have_text("flown by ACME_1")

    page.goto(f"{live_logs.url}/logs/")
    page.locator("#trends-link").click()
    row = page.locator('#trend-table tr[data-drone="ACME_1"]')
    expect(row).to_have_class("drifting")
    expect(row.locator(".badge.warn")).to_have_text("drifting from its history")
    expect(row.locator(".trend-chart")).to_have_attribute("data-points", "6")
    expect(row.locator("canvas")).to_have_count(1)
    row.get_by_role("link", name="ACME_1").click()
    card = page.locator('[data-check="vibration"]')
    expect(card).to_have_class("card trend-card drifting")
    expect(card.locator(".trend-chart")).to_have_attribute("data-points", "6")

"""The planner in a real browser shows the other drones' reservations on the map, and
marks the leg of the plan that would meet one, naming the drone, before anything is sent."""

from __future__ import annotations

import pytest

from fleet.models import Drone
from tests.conftest import login
from tests.missions.conftest import online_drone

from .test_separation import crossing, start

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_reservations_are_drawn_and_a_conflicting_leg_is_marked(page, live_asgi, world_tx):
    online_drone(world_tx.org, "ACME_A", north=-150)
    online_drone(world_tx.org, "ACME_B", east=-150)
    assert start(world_tx.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    # It took off: its reservation holds until it lands, however slowly the page loads
    # (one never seen airborne by its take-off's deadline is taken to have landed).
    Drone.objects.filter(drone_id="ACME_A").update(airborne=True, alt=20.0)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    page.wait_for_function("window.skyhivePlanner && window.skyhiveAirspace")
    page.wait_for_selector("path.reserved-leg", state="attached")
    tooltip_source = page.evaluate(
        "() => { let t = []; window.skyhivePlanner.map.eachLayer((l) => { if (l.getTooltip && l.getTooltip() && l.options.className === 'reserved-leg') t.push(l.getTooltip().getContent()); }); return t; }"
    )
    assert any(t.startswith("ACME_A: ") for t in tooltip_source), tooltip_source
    steps = [{"command": s["command"], "params": s.get("params", {})} for s in crossing((0, -150), (0, 150), 20)["steps"]]  # fmt: skip
    page.evaluate("(s) => window.skyhivePlanner.steps.push(...s)", steps)
    page.select_option("#drone-choice", "ACME_B")
    page.wait_for_selector("#airspace-conflicts:not([hidden])")
    assert "drone ACME_A" in page.locator("#airspace-conflicts li").first.inner_text()
    page.wait_for_selector("path.conflicting-leg", state="attached")
    # 20 m higher there is no conflict, and the marks go.
    page.evaluate(
        "() => { window.skyhivePlanner.steps[1].params.altitude = 40; document.dispatchEvent(new CustomEvent('skyhive:steps-changed')); }"
    )
    page.wait_for_selector("#airspace-conflicts", state="hidden")
    assert page.locator("path.conflicting-leg").count() == 0

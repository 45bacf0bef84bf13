"""The batteries page and the drone page's battery choice in a real browser: a member
names a pack, fits it to a drone that reports none, and the list shows its health,
cycles and retirement."""

from __future__ import annotations

import pytest

from batteries.models import Battery, BatteryPolicy
from batteries.usage import judge
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_a_member_names_a_pack_and_fits_it_before_flight(page, live_asgi, world_tx):
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/batteries/")
    page.fill("#battery-new input[name=serial]", "PACK-7")
    page.fill("#battery-new input[name=rated_energy_wh]", "80")
    page.click("#battery-new button[type=submit]")
    row = page.locator("#battery-list tr[data-serial='PACK-7']")
    assert row.get_attribute("data-retired") == "no"

    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.select_option("#battery-choice select[name=battery]", label="PACK-7")
    page.click("#battery-choice button[type=submit]")
    assert page.locator("#battery-carried").inner_text().startswith("PACK-7")
    assert Battery.objects.get(serial="PACK-7").drone.drone_id == "ACME_1"

    # Worn: 60 Wh of a rated 80 (75 %) under the 80 % threshold.
    Battery.objects.filter(serial="PACK-7").update(health=0.75, cycles=41.5, capacity_wh=60)
    BatteryPolicy.objects.create(organisation=world_tx.org, health_threshold=0.8)
    judge(Battery.objects.get(serial="PACK-7"))
    page.goto(f"{live_asgi.url}/batteries/")
    row = page.locator("#battery-list tr[data-serial='PACK-7']")
    assert row.get_attribute("data-retired") == "yes"
    assert "75 %" in row.inner_text() and "41.50" in row.inner_text()
    assert "retired: health 75% below 80%" in row.inner_text()
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    assert "battery PACK-7 retired" in page.locator("#remote-id .reasons").inner_text()
    assert not [e for e in errors if "Content Security Policy" in e], errors

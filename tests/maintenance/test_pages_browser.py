"""The maintenance pages in a real browser: an admin adds a schedule on the fleet's due
list, which then leads to the drone's page, where the admin signs the task off and the
log shows it."""

from __future__ import annotations

import pytest

from maintenance.models import Schedule
from tests.conftest import login

from .support import flown

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_an_admin_signs_a_due_task_off_from_the_drone_page(page, live_asgi, world_tx):
    flown(world_tx.drone, minutes=15, count=2)
    login(page, live_asgi, "owner")
    page.goto(f"{live_asgi.url}/maintenance/")
    form = page.locator("#maintenance-add-schedule form")
    form.locator("input[name=name]").fill("Frame inspection")
    form.locator("select[name=drone]").select_option("ACME_1")
    form.locator("input[name=every_flights]").fill("2")
    form.locator("button[type=submit]").click()
    page.wait_for_load_state()
    assert Schedule.objects.get().every_flights == 2
    row = page.locator("#maintenance-due tr[data-drone=ACME_1]")
    assert "Frame inspection" in row.inner_text()
    assert "due now at 2 flights" in row.inner_text()
    row.locator("a").click()
    page.wait_for_load_state()
    item = page.locator("#maintenance-items tr[data-item]")
    assert item.get_attribute("data-status") == "due"
    page.fill("#maintenance-sign-off textarea[name=notes]", "Frame checked, no cracks")
    page.fill("#maintenance-sign-off textarea[name=parts]", "arm bolt M3\nzip tie")
    page.click("#maintenance-sign-off button[type=submit]")
    page.wait_for_load_state()
    assert item.get_attribute("data-status") == "ok"
    log = page.locator("#maintenance-log tr[data-entry]")
    assert log.count() == 1
    assert "owner" in log.inner_text() and "arm bolt M3, zip tie" in log.inner_text()

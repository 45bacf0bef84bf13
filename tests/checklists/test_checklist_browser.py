"""In a real browser: the fleet table's *Fit to fly* column says why a drone is not
airworthy and where its checklist stands; the drone's checklist page runs a checklist (an
unticked item fails it, ticking every item passes it)."""

from __future__ import annotations

import pytest

from checklists import definitions
from checklists.models import Policy, Run, Template
from fleet.models import Drone
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

FAILING = {
    "protocol": "mavlink",
    "connected": True,
    "remote_id": {"ok": False, "error": "transmitter fault"},
}


def ready_cell(page):  # type: ignore[no-untyped-def]
    cell = page.locator('#drone-table tr[data-drone="ACME_1"] [data-field="ready"]')
    cell.wait_for()
    return cell


def test_the_fleet_shows_why_and_the_checklist_page_runs_one(page, live_asgi, world_tx):
    Policy.objects.create(organisation=world_tx.org, required=True, valid_minutes=30)
    items = [
        {"kind": "manual", "text": "Propellers tight"},
        {"kind": "auto", "check": "battery", "threshold": 0.6},
        {"kind": "auto", "check": "airworthy"},
    ]
    definitions.create_template(
        world_tx.org, {"name": "Before flight", "items": items}, world_tx.owner
    )
    Drone.objects.filter(drone_id="ACME_1").update(
        online=True, lat=40.63, lon=-8.65, alt=0.0, battery_remaining=0.9, fc=FAILING
    )
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    cell = ready_cell(page)
    assert "not airworthy: Remote ID failing: transmitter fault" in cell.inner_text()
    assert "checklist not run" in cell.inner_text()

    Drone.objects.filter(drone_id="ACME_1").update(fc={**FAILING, "remote_id": {"ok": True}})
    cell.locator("a").click()
    page.wait_for_url("**/checklists/drones/ACME_1/")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.click("#drone-checklist")
    page.wait_for_url("**/checklists/drones/ACME_1/")
    assert page.locator("#checklist-status").inner_text() == "not run"
    page.click(".checklist-form button[type=submit]")
    assert page.locator("#checklist-status").inner_text() == "failed"
    assert "not confirmed: Propellers tight" in page.locator(".failures").inner_text()
    page.check(".checklist-form input[name=confirmed]")
    page.click(".checklist-form button[type=submit]")
    assert page.locator("#checklist-status").inner_text() == "passed"
    assert "battery charge at least 0.6: 0.9" in page.locator("#checklist-runs").inner_text()
    assert [r.passed for r in Run.objects.order_by("at")] == [False, True]

    page.goto(f"{live_asgi.url}/")
    assert "airworthy" in ready_cell(page).inner_text()
    assert "checklist passed" in ready_cell(page).inner_text()


def test_an_admin_defines_a_checklist_on_the_page(page, live_asgi, world_tx):
    login(page, live_asgi, "owner")
    page.goto(f"{live_asgi.url}/checklists/")
    page.fill("#template-form input[name=name]", "Before flight")
    page.click("#template-form button[type=submit]")
    assert "Not saved: items: must be a non-empty list" in page.locator(".messages").inner_text()
    assert not Template.objects.exists()

    page.fill("#template-form input[name=name]", "Before flight")
    page.fill("#template-form textarea[name=manual]", "Propellers tight\nArea clear")
    page.check("#template-form input[name=auto_battery]")
    page.fill("#template-form input[name=threshold_battery]", "0.7")
    page.check("#template-form input[name=auto_airworthy]")
    page.click("#template-form button[type=submit]")
    assert "Before flight" in page.locator("#checklist-templates").inner_text()
    assert Template.objects.get().items == [
        {"kind": "manual", "text": "Propellers tight"},
        {"kind": "manual", "text": "Area clear"},
        {"kind": "auto", "check": "battery", "threshold": 0.7},
        {"kind": "auto", "check": "airworthy", "threshold": None},
    ]
    page.check("#rule-form input[name=required]")
    page.click("#rule-form button[type=submit]")
    assert "A passed checklist is required" in page.locator("#checklist-rule").inner_text()
    assert Policy.objects.get(organisation=world_tx.org).required

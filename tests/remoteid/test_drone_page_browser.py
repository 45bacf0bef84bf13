"""The drone page's Remote ID card in a real browser: the serial number, what the
broadcast declares of the aircraft, what the module reports and the airworthiness verdict
with its reasons."""

from __future__ import annotations

import pytest

from fleet.models import Drone, Organisation
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_the_drone_page_shows_why_a_drone_may_not_arm(page, live_asgi, world_tx):
    Organisation.objects.filter(pk=world_tx.org.pk).update(require_remote_id=True)
    Drone.objects.filter(drone_id="ACME_1").update(
        serial_number="MFR1C123456789ABC",
        eu_category=1,
        eu_class=3,
        fc={"protocol": "mavlink", "remote_id": {"ok": False, "error": "transmitter fault"}},
    )
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    card = page.locator("#remote-id")
    assert "MFR1C123456789ABC" in card.inner_text()
    terms, details = card.locator("dt").all_inner_texts(), card.locator("dd").all_inner_texts()
    declared = dict(zip(terms, details, strict=True))
    assert declared["UA type"] == "helicopter or multirotor"
    assert (declared["EU category"], declared["EU class"]) == ("open", "C2")
    assert "module failing: transmitter fault" in card.inner_text()
    assert card.locator("[data-airworthy]").get_attribute("data-airworthy") == "no"
    assert card.locator(".reasons li").all_inner_texts() == [
        "Remote ID failing: transmitter fault",
        "the organisation has no operator registration number for Remote ID to broadcast",
    ]

    Organisation.objects.filter(pk=world_tx.org.pk).update(operator_id="FIN87astrdge12k8")
    Drone.objects.filter(drone_id="ACME_1").update(
        fc={"protocol": "mavlink", "remote_id": {"ok": True, "error": ""}}
    )
    page.reload()
    assert "module good to arm" in card.inner_text()
    assert card.locator("[data-airworthy]").get_attribute("data-airworthy") == "yes"
    assert card.locator(".reasons li").count() == 0

"""The organisation settings page's Remote ID section in a real browser: an admin enters
the EU operator number with its secret characters; a wrong checksum is shown and changes
nothing; the stored public part saves back unchanged."""

from __future__ import annotations

import pytest

from accounts.models import AuditEvent
from fleet.models import Organisation
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

SECTION = "#remote-id-settings"


def save(page, operator_id: str) -> None:  # type: ignore[no-untyped-def]
    page.fill(f"{SECTION} input[name=operator_id]", operator_id)
    page.click(f"{SECTION} button[type=submit]")
    page.wait_for_load_state()


def test_an_admin_sets_the_operator_number_on_the_settings_page(page, live_asgi, world_tx):
    login(page, live_asgi, "owner")
    page.goto(f"{live_asgi.url}/accounts/organisation/")
    save(page, "FIN87astrdge12k9-xyz")
    assert "wrong checksum" in page.locator(f"{SECTION} [role=alert]").inner_text()
    assert Organisation.objects.get(slug="acme").operator_id == ""

    save(page, "FIN87astrdge12k8-xyz")
    assert "Remote ID settings saved" in page.locator(".messages").inner_text()
    assert page.input_value(f"{SECTION} input[name=operator_id]") == "FIN87astrdge12k8"
    page.check(f"{SECTION} input[name=require_remote_id]")
    page.click(f"{SECTION} button[type=submit]")
    page.wait_for_load_state()
    acme = Organisation.objects.get(slug="acme")
    assert (acme.operator_id, acme.require_remote_id) == ("FIN87astrdge12k8", True)
    actions = list(
        AuditEvent.objects.filter(action="remote_id.operator")
        .order_by("at")
        .values_list("detail", flat=True)
    )
    assert actions == [
        {"changed": {"operator_id": "FIN87astrdge12k8"}},
        {"changed": {"require_remote_id": True}},
    ]

"""The alert banner on every page, in a real browser: shown live, dismissed for good."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest
from django.db import connections

from tests.conftest import login

from .test_alerts import critical_alarm

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_a_critical_alarm_shows_on_the_open_page_and_stays_dismissed(page, live_asgi, world_tx):
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/")
    # The socket has joined the organisation's group: it says what is open once it has.
    page.wait_for_function("window.skyhiveAlerts && window.skyhiveAlerts.recentSeen")

    def alarm() -> None:
        critical_alarm(world_tx.org, world_tx.drone, "battery critical")
        connections.close_all()

    # As the gateway would: another thread (the browser's event loop runs in this one).
    with ThreadPoolExecutor(1) as pool:
        pool.submit(alarm).result()
    page.wait_for_selector("#alert-banner:not([hidden]) .alert-critical")
    assert "battery critical" in page.locator("#alert-list").inner_text()
    # Another page opened afterwards shows it too, until it is dismissed.
    page.goto(f"{live_asgi.url}/telemetry/")
    page.wait_for_selector("#alert-banner:not([hidden]) .alert-critical")
    page.click(".alert-dismiss")
    assert page.locator("#alert-banner").is_hidden()
    page.goto(f"{live_asgi.url}/")
    # The open alert came again with the socket's first message, and stays dismissed.
    page.wait_for_function("window.skyhiveAlerts && window.skyhiveAlerts.recentSeen")
    assert page.evaluate("window.skyhiveAlerts.shown") == []
    assert page.locator("#alert-banner").is_hidden()

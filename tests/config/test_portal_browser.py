"""The portal in a real browser: log in, navigate, read on a phone-sized screen."""

import pytest
from playwright.sync_api import expect

from tests.conftest import login

pytestmark = pytest.mark.browser


def test_a_user_logs_in_and_navigates_the_portal(page, live_asgi, world_tx):
    login(page, live_asgi, "owner")
    assert page.locator("h1").first.inner_text().startswith("Fleet")
    # The table is filled by the page's script after the load.
    expect(page.locator("#drone-table tbody tr")).to_have_count(1)
    assert page.locator("#drone-table").inner_text().count("ACME_1") == 1
    assert "GLOBEX_1" not in page.content()
    page.click("nav >> text=Missions")
    assert page.locator("h1").first.inner_text() == "Missions"
    page.click("nav >> text=Telemetry")
    assert page.locator("h1").first.inner_text() == "Telemetry"


def test_wrong_password_shows_an_error_in_the_page(page, live_asgi, world_tx):
    login(page, live_asgi, "owner", "not the password")
    assert page.get_by_role("alert").inner_text().startswith("Your username and password")


def test_the_navigation_folds_into_a_menu_on_a_phone(browser, live_asgi, world_tx):
    context = browser.new_context(viewport={"width": 390, "height": 800}, is_mobile=True)
    page = context.new_page()
    try:
        login(page, live_asgi, "owner")
        nav = page.locator("nav.mainnav")
        assert not nav.is_visible()
        page.click("label.nav-toggle-label")
        assert nav.is_visible()
        # Nothing overflows the screen sideways.
        width = page.evaluate("document.documentElement.scrollWidth")
        assert width <= 390
    finally:
        context.close()

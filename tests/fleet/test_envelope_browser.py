"""The flight-envelope page in a real browser: the form opens only once the stored
envelope is in it, an admin's edit is saved, and anyone else only reads it."""

from __future__ import annotations

import time

import pytest

from fleet.models import Organisation
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

STORED = {"max_height": 90, "max_distance": 700, "home": [40.6303, -8.6575]}
API = "**/api/v1/organisations/*/envelope/"


def held_until_released(page):  # type: ignore[no-untyped-def]
    """Hold the page's first read of the envelope; the returned list gets its route."""
    held = []

    def hold(route) -> None:  # type: ignore[no-untyped-def]
        if held or route.request.method != "GET":
            route.continue_()
        else:
            held.append(route)

    page.route(API, hold)
    return held


def wait_held(page, held) -> None:  # type: ignore[no-untyped-def]
    # The page asks as it loads (within 1 s here); the request reaches `hold` as soon as
    # Playwright dispatches events.
    deadline = time.monotonic() + 10.0
    while not held and time.monotonic() < deadline:
        page.wait_for_timeout(20)
    assert len(held) == 1


def test_an_admin_edits_only_once_the_stored_envelope_is_in_the_form(page, live_asgi, world_tx):
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=STORED)
    login(page, live_asgi, "owner")
    held = held_until_released(page)
    page.goto(f"{live_asgi.url}/organisation/envelope/")
    wait_held(page, held)
    # Typed now, it would be overwritten by the stored envelope when it came.
    assert page.locator("input[name=max_height]").is_disabled()
    assert page.locator("#envelope-save").is_disabled()
    assert "Loading" in page.locator("#envelope-status").inner_text()

    held[0].continue_()
    page.wait_for_selector("input[name=max_height]:enabled")
    assert page.input_value("input[name=max_height]") == "90"
    assert page.input_value("input[name=home]") == "40.6303, -8.6575"
    page.fill("input[name=max_height]", "80")
    page.click("#envelope-save")
    page.wait_for_function(
        "document.querySelector('#envelope-status').textContent.includes('Saved')"
    )
    envelope = Organisation.objects.get(pk=world_tx.org.pk).envelope
    assert envelope["max_height"] == 80 and envelope["max_distance"] == 700


def test_a_viewer_reads_the_envelope_and_cannot_change_it(page, live_asgi, world_tx):
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=STORED)
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/organisation/envelope/")
    page.wait_for_function("document.querySelector('[name=max_height]').value === '90'")
    assert page.locator("input[name=max_height]").is_disabled()
    assert page.locator("#envelope-save").is_disabled()
    assert "Only organisation admins" in page.locator("#envelope-status").inner_text()


def test_an_envelope_that_cannot_be_loaded_leaves_the_form_closed_and_says_so(
    page, live_asgi, world_tx
):
    login(page, live_asgi, "owner")
    page.route(API, lambda route: route.fulfill(status=503, body="{}"))
    page.goto(f"{live_asgi.url}/organisation/envelope/")
    page.wait_for_function(
        "document.querySelector('#envelope-status').textContent.includes('could not be loaded')"
    )
    assert page.locator("#envelope-save").is_disabled()

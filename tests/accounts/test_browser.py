"""The members and security pages in a real browser."""

from __future__ import annotations

import time
from base64 import b32decode

import pytest
from django_otp.oath import TOTP
from playwright.sync_api import expect

from accounts import members
from fleet.models import Membership
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PASSWORD = "correct horse battery staple"


def row(page, name: str):  # type: ignore[no-untyped-def]
    return page.locator(f'#member-list tr[data-member="{name}"]')


def test_an_admin_invites_changes_a_role_and_removes_a_member(page, live_asgi, world_tx):
    login(page, live_asgi, "owner")
    page.click("nav >> text=Members")
    assert page.locator("h1").inner_text() == "Members of Acme"
    page.fill("#invite input[name=email]", "pilot@example.org")
    page.select_option("#invite select[name=role]", "operator")
    page.click("#invite button[type=submit]")
    assert "Invitation sent to pilot@example.org" in page.locator(".messages").inner_text()
    assert page.locator('#invitation-list tr[data-email="pilot@example.org"]').count() == 1

    row(page, "viewer").locator("select[name=role]").select_option("operator")
    row(page, "viewer").locator("text=Change").click()
    page.wait_for_load_state()
    assert "viewer is now Operator" in page.locator(".messages").inner_text()
    assert Membership.objects.get(user=world_tx.viewer).role == "operator"

    page.once("dialog", lambda dialog: dialog.accept())
    row(page, "operator").locator("text=Remove").click()
    page.wait_for_load_state()
    assert row(page, "operator").count() == 0
    assert not Membership.objects.filter(user=world_tx.operator).exists()

    row(page, "owner").locator("select[name=role]").select_option("viewer")
    row(page, "owner").locator("text=Change").click()
    page.wait_for_load_state()
    assert "at least one admin" in page.get_by_role("alert").inner_text()


def test_an_invitee_signs_up_through_the_link_and_lands_in_the_organisation(
    browser, live_asgi, world_tx
):
    invited = members.invite(world_tx.org, "pilot@example.org", "operator", world_tx.owner)
    context = browser.new_context()
    page = context.new_page()
    try:
        page.goto(f"{live_asgi.url}/accounts/invitation/{invited.key}/")
        assert page.locator("h1").inner_text() == "Join Acme"
        page.fill("input[name=username]", "pilot")
        page.fill("input[name=password1]", PASSWORD)
        page.fill("input[name=password2]", PASSWORD)
        page.click("button[type=submit]")
        page.wait_for_load_state()
        assert "Welcome to Acme (Operator)" in page.locator(".messages").inner_text()
        assert page.locator(".account .role").inner_text() == "Operator"
        # The table is filled by the page's script after the load.
        expect(page.locator("#drone-table")).to_contain_text("ACME_1")
    finally:
        context.close()


def test_the_security_page_makes_and_revokes_a_token_and_turns_on_two_factor(
    page, live_asgi, world_tx
):
    login(page, live_asgi, "operator")
    page.click("nav >> text=Security")
    assert "signed in" in page.locator("#sign-in-list").inner_text()
    page.fill("#tokens input[name=name]", "survey script")
    page.select_option("#tokens select[name=scope]", "read")
    page.click("#tokens button[type=submit]")
    key = page.locator("#new-token-key").input_value()
    assert key.startswith("sky_")
    listed = page.locator('#token-list tr[data-token="survey script"]')
    assert "Read-only" in listed.inner_text() and key not in listed.inner_text()
    listed.locator("text=Revoke").click()
    # Each click loads a new page; `expect` waits for it (a loaded machine serves it late).
    expect(page.locator('#token-list tr[data-token="survey script"]')).to_contain_text("revoked")

    page.click("text=Set up an authenticator app")
    expect(page.locator(".qr svg")).to_be_visible()
    secret = page.locator("#totp-secret").inner_text()
    totp = TOTP(b32decode(secret), step=30, t0=0, digits=6)
    totp.time = time.time()
    page.fill("input[name=password]", PASSWORD)  # none enrolled yet: the password proves it
    page.fill("input[name=code]", str(totp.token()).zfill(6))
    page.click("#two-factor button[type=submit]")
    expect(page.locator(".messages")).to_contain_text("Two-factor sign-in is on")
    expect(page.locator("#second-factor .badge")).to_contain_text("On")

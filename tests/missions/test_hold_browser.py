"""One drone of a two-drone mission held from its own page, seen on the mission page:
that drone alone shows holding, the mission is not paused, and Resume reaches it."""

from __future__ import annotations

import threading

import pytest

from missions.models import Assignment, Mission
from missions.progress import apply_progress
from onboard import protocol
from tests.conftest import login

from .test_hold_per_drone import two_drone_mission

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_the_mission_page_shows_the_one_held_drone_and_resumes_it(page, live_asgi, world_tx):
    mission, held = two_drone_mission(world_tx.org)
    first = held.drone
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
    page.wait_for_selector("#live-status.ok")
    assert page.locator("#resume-mission").is_hidden()

    # ACME_A's page sent Hold; its agent reports the pause (as the gateway would, off the
    # browser driver's event loop so the push goes out).
    paused = protocol.MissionProgress(str(mission.pk), str(held.pk), "paused")
    gateway = threading.Thread(target=apply_progress, args=(first, paused))
    gateway.start()
    gateway.join()
    page.wait_for_selector("#resume-mission:not([hidden])")
    page.wait_for_function(
        "document.querySelector('#drone-progress tr[data-drone=\"ACME_A\"] .assignment')"
        "?.textContent.includes('holding')"
    )
    b_state = page.inner_text('#drone-progress tr[data-drone="ACME_B"] .assignment')
    assert "holding" not in b_state
    assert Mission.objects.get(pk=mission.pk).held is False

    page.click("#resume-mission")
    page.wait_for_selector("#pause-mission:not([hidden])")
    assert not Assignment.objects.get(pk=held.pk).held
    assert page.locator("#mission-error").is_hidden()

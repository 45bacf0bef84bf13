"""Operator controls in a real browser: mission Pause and Resume in one click each; Arm is
not sent until the drone's id has been typed."""

from __future__ import annotations

import json
import threading
import time

import pytest

from fleet.models import Drone
from missions.creation import create_mission
from missions.models import Mission
from missions.progress import apply_progress
from missions.startstop import start_mission
from onboard import protocol
from tests.conftest import login

from .conftest import online_drone
from .test_api import _mission_body

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_pause_then_resume_on_the_mission_page_changes_the_mission(page, live_asgi, world_tx):
    drone = online_drone(world_tx.org, "ACME_1")
    body = _mission_body()
    mission = create_mission(organisation=world_tx.org, name=body["name"], steps=body["steps"])
    start_mission(mission, drone=drone)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
    page.wait_for_selector("#live-status.ok")
    assert page.locator("#resume-mission").is_hidden()
    page.click("#pause-mission")
    page.wait_for_selector("#resume-mission:not([hidden])")
    assert Mission.objects.get(pk=mission.pk).held is True
    assert page.locator("#pause-mission").is_hidden()
    page.click("#resume-mission")
    page.wait_for_selector("#pause-mission:not([hidden])")
    assert Mission.objects.get(pk=mission.pk).held is False
    assert page.locator("#mission-error").is_hidden()
    # The drone held from its own page: the mission page offers Resume on the push.
    assignment = mission.assignments.get()
    paused = protocol.MissionProgress(str(mission.pk), str(assignment.pk), "paused")
    # As the gateway does it: off the browser driver's event loop, so the push goes out.
    gateway = threading.Thread(target=apply_progress, args=(drone, paused))
    gateway.start()
    gateway.join()
    page.wait_for_selector("#resume-mission:not([hidden])")


def test_arm_without_the_typed_confirmation_sends_nothing(page, live_asgi, world_tx):
    online_drone(world_tx.org, "ACME_1")
    sent: list[dict] = []

    def answer(route) -> None:  # type: ignore[no-untyped-def]
        sent.append(json.loads(route.request.post_data))
        route.fulfill(json={"ok": True, "result": {}, "request_id": "0" * 32})

    page.route("**/api/v1/drones/ACME_1/commands/", answer)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.click('form[data-command="arm"] button')
    page.wait_for_function(
        "document.getElementById('command-result').textContent.includes('not sent')"
    )
    page.fill('form[data-command="takeoff"] input[name=confirm]', "ACME_2")
    page.click('form[data-command="takeoff"] button')
    page.wait_for_timeout(300)
    assert sent == []

    page.fill('form[data-command="arm"] input[name=confirm]', "ACME_1")
    page.click('form[data-command="arm"] button')
    page.wait_for_function("document.getElementById('command-result').dataset.status === 'ok'")
    page.click('form[data-command="return"] button')  # one click, no confirmation
    page.wait_for_function(
        "document.getElementById('command-result').textContent.startsWith('return: ok')"
    )
    assert sent == [{"command": "arm", "params": {}}, {"command": "return", "params": {}}]


def test_the_fleet_table_holds_a_drone_in_one_click(page, live_asgi, world_tx):
    online_drone(world_tx.org, "ACME_1")
    sent: list[dict] = []

    def answer(route) -> None:  # type: ignore[no-untyped-def]
        sent.append(json.loads(route.request.post_data))
        route.fulfill(json={"ok": True, "result": {"mode": "hold"}, "request_id": "0" * 32})

    page.route("**/api/v1/drones/ACME_1/commands/", answer)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    row = 'tr[data-drone="ACME_1"]'
    page.click(f'{row} button[data-command="hold"]')
    page.wait_for_selector(f'{row} .control-result[data-status="ok"]')
    assert sent == [{"command": "hold", "params": {}}]


def test_the_answer_reaches_the_row_when_the_table_is_drawn_again_meanwhile(
    page, live_asgi, world_tx
):
    online_drone(world_tx.org, "ACME_1")
    held = []

    def hold(route) -> None:  # type: ignore[no-untyped-def]
        held.append(route)

    page.route("**/api/v1/drones/ACME_1/commands/", hold)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    row = 'tr[data-drone="ACME_1"]'
    page.wait_for_selector(row)
    page.evaluate("document.querySelector('tr[data-drone=\"ACME_1\"]').dataset.old = 'yes'")
    page.click(f'{row} button[data-command="hold"]')
    deadline = time.monotonic() + 10.0  # the click posts at once
    while not held and time.monotonic() < deadline:
        page.wait_for_timeout(20)
    assert len(held) == 1
    # A search draws the table's rows anew (as its refresh every 15 s does).
    page.fill("#fleet-search", "ACME")
    page.wait_for_selector(f"{row}:not([data-old])")
    held[0].fulfill(json={"ok": True, "result": {"mode": "hold"}, "request_id": "0" * 32})
    page.wait_for_selector(f'{row} .control-result[data-status="ok"]')


def test_resume_on_the_drone_page_resumes_the_mission_it_flies(page, live_asgi, world_tx):
    drone = online_drone(world_tx.org, "ACME_1")
    body = _mission_body()
    mission = create_mission(organisation=world_tx.org, name=body["name"], steps=body["steps"])
    start_mission(mission, drone=drone)
    Mission.objects.filter(pk=mission.pk).update(held=True)
    Drone.objects.filter(pk=drone.pk).update(mission={"mission_id": str(mission.pk), "index": 3})
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.click('form[data-mission-action="resume"] button')
    page.wait_for_function("document.getElementById('command-result').dataset.status === 'ok'")
    assert Mission.objects.get(pk=mission.pk).held is False
    page.click('form[data-mission-action="resume"] button')  # not paused any more: 409
    page.wait_for_function(
        "document.getElementById('command-result').textContent.startsWith('resume: 409')"
    )

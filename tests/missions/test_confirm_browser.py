"""Confirmations beyond the envelope's defaults, and offending legs, in a real browser.

The ground's own answers drive the pages: the first request of each flow reaches the real
server, which refuses it (409 confirmation_required, or outside_envelope) without sending
anything; the page asks, then sends again with `confirm_beyond_defaults`.
"""

from __future__ import annotations

import json

import pytest

from fleet.models import CommandLog, Organisation
from missions.models import Mission, MissionStatus
from tests.conftest import login

from .conftest import online_drone, point_at

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

RAISED = {"max_height": 300.0, "max_distance": 3000.0}


def test_the_drone_page_asks_for_the_typed_id_before_flying_beyond_the_defaults(
    page, live_asgi, world_tx
):
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=RAISED)
    online_drone(world_tx.org, "ACME_1")
    sent: list[dict] = []

    def answer(route) -> None:  # type: ignore[no-untyped-def]
        body = json.loads(route.request.post_data)
        sent.append(body)
        if body.get("confirm_beyond_defaults"):
            # Stands in for the drone's reply: no drone answers in this test.
            route.fulfill(json={"ok": True, "result": {}, "request_id": "0" * 32})
        else:
            route.continue_()

    page.route("**/api/v1/drones/ACME_1/commands/", answer)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.fill('form[data-command="altitude"] input[name=value]', "150")
    page.click('form[data-command="altitude"] button')
    page.wait_for_selector("#beyond-defaults:not([hidden])")
    assert "default maximum height of 120 m" in page.inner_text("#beyond-defaults-message")
    assert CommandLog.objects.get().outcome == "rejected"  # refused by the ground, unsent

    page.fill("#beyond-defaults-typed", "ACME_2")
    page.click("#beyond-defaults-send")
    page.wait_for_function(
        "document.getElementById('command-result').textContent.includes('not sent')"
    )
    assert len(sent) == 1

    page.fill("#beyond-defaults-typed", "ACME_1")
    page.click("#beyond-defaults-send")
    page.wait_for_function("document.getElementById('command-result').dataset.status === 'ok'")
    assert page.locator("#beyond-defaults").is_hidden()
    assert sent == [
        {"command": "altitude", "params": {"value": 150}},
        {"command": "altitude", "params": {"value": 150}, "confirm_beyond_defaults": True},
    ]


def add_step(page, command: str, **params: float) -> None:  # type: ignore[no-untyped-def]
    page.select_option("#new-step-command", command)
    page.click("#add-step")
    step = page.locator("#step-list .step").last
    for name, value in params.items():
        step.locator(f"input[name={name}]").fill(str(value))
        step.locator(f"input[name={name}]").press("Tab")  # the change event


def plan_north(page, north: float) -> None:  # type: ignore[no-untyped-def]
    home, target = point_at(0, 0), point_at(north, 0)
    page.click("#step-details summary")  # the step list opens for editing
    add_step(page, "arm")
    add_step(page, "takeoff", altitude=10)
    add_step(page, "navigate", lat=home[0], lon=home[1])
    add_step(page, "navigate", lat=target[0], lon=target[1])
    add_step(page, "land")


def test_the_planner_asks_for_confirm_before_sending_a_mission_beyond_the_defaults(
    page, live_asgi, world_tx
):
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=RAISED)
    online_drone(world_tx.org, "ACME_1")
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    plan_north(page, 1500)
    page.fill("#mission-name", "Far survey")
    page.click("#send-mission")
    page.wait_for_selector("#beyond-defaults:not([hidden])")
    assert "default maximum distance of 1000 m" in page.inner_text("#beyond-defaults-message")
    assert "beyond-defaults" in page.locator("#step-list .step").nth(3).get_attribute("class")
    assert not Mission.objects.exists()

    page.fill("#beyond-defaults-typed", "yes")
    page.click("#beyond-defaults-send")
    page.wait_for_selector("#planner-error:not([hidden])")
    assert not Mission.objects.exists()

    page.fill("#beyond-defaults-typed", "CONFIRM")
    page.click("#beyond-defaults-send")
    page.wait_for_url("**/missions/*-*/")
    mission = Mission.objects.get(name="Far survey")
    assert mission.status == MissionStatus.RUNNING
    assert mission.assignments.get().drone.drone_id == "ACME_1"


def test_the_planner_marks_a_step_whose_leg_crosses_an_exclusion_zone(page, live_asgi, world_tx):
    circle = {"center": list(point_at(100, 0)), "radius": 20}
    fence = {"version": 2, "polygons": [], "circles": [{"inclusion": False, "circle": circle}]}
    Organisation.objects.filter(pk=world_tx.org.pk).update(
        envelope={"geoFence": fence, "home": list(point_at(0, 0))}
    )
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    plan_north(page, 200)
    page.click("#send-mission")
    page.wait_for_selector("#step-list .step.outside-envelope")
    marked = page.locator("#step-list .step.outside-envelope")
    assert marked.count() == 1
    assert page.locator("#step-list .step").nth(3).get_attribute("class").count("outside") == 1
    assert "exclusion circle 0" in marked.get_attribute("title")
    assert page.locator("#planner-map path.offending-leg").count() == 1
    assert "Step 3" in page.inner_text("#planner-error")
    assert not Mission.objects.exists()


def test_the_mission_page_starts_a_draft_beyond_the_defaults_once_confirmed(
    page, live_asgi, world_tx
):
    from missions.creation import create_mission

    from .test_envelope import body

    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=RAISED)
    online_drone(world_tx.org, "ACME_1")
    steps = body(1500)["steps"]
    organisation = Organisation.objects.get(pk=world_tx.org.pk)
    mission = create_mission(organisation=organisation, name="far", steps=steps, confirmed=True)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
    page.click("#start-mission")
    page.wait_for_selector("#beyond-defaults:not([hidden])")
    assert "Step 3" in page.inner_text("#beyond-defaults-message")
    assert "default maximum distance" in page.inner_text("#beyond-defaults-message")
    page.fill("#beyond-defaults-typed", "ok")
    page.click("#beyond-defaults-send")
    page.wait_for_selector("#mission-error:not([hidden])")
    assert Mission.objects.get(pk=mission.pk).status == MissionStatus.DRAFT

    page.fill("#beyond-defaults-typed", "CONFIRM")
    page.click("#beyond-defaults-send")
    page.wait_for_selector("#pause-mission")  # reloaded: the mission runs
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING
    assert mission.assignments.get().drone.drone_id == "ACME_1"


def test_the_fleet_table_resends_with_the_confirmation_once_the_id_is_typed(
    page, live_asgi, world_tx
):
    online_drone(world_tx.org, "ACME_1")
    sent: list[dict] = []
    typed: list[str] = []

    def answer(route) -> None:  # type: ignore[no-untyped-def]
        body = json.loads(route.request.post_data)
        sent.append(body)
        if body.get("confirm_beyond_defaults"):
            route.fulfill(json={"ok": True, "result": {}, "request_id": "0" * 32})
        else:  # the ground's answer to a move beyond the defaults (the API's contract)
            error = "The target is 1500 m from home, beyond the default maximum distance."
            route.fulfill(status=409, json={"error": error, "code": "confirmation_required"})

    def reply(dialog) -> None:  # type: ignore[no-untyped-def]
        typed.append(dialog.message)
        dialog.accept(["ACME_2", "ACME_1"][len(typed) - 1])

    page.route("**/api/v1/drones/ACME_1/commands/", answer)
    page.on("dialog", reply)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    row = 'tr[data-drone="ACME_1"]'
    page.click(f'{row} button[data-command="return"]')
    page.wait_for_selector(f'{row} .control-result[data-status="error"]')
    assert sent == [{"command": "return", "params": {}}]  # a wrong id: not sent again
    page.click(f'{row} button[data-command="return"]')
    page.wait_for_selector(f'{row} .control-result[data-status="ok"]')
    assert sent[-1] == {"command": "return", "params": {}, "confirm_beyond_defaults": True}
    assert all("Type ACME_1" in message for message in typed)


# The page's own fetch, with every envelope check held from now until the test lets them
# go (the planner's own check of the confirmed plan, and any the plan's drawing asks for
# meanwhile: they go to the same address), and a count of the step lists drawn.
HOLD_CHECKS = """() => {
  const real = window.fetch;
  window.held = [];
  window.holding = true;
  window.stepsDrawn = 0;
  window.releaseChecks = () => { window.holding = false; window.held.forEach((go) => go()); };
  document.addEventListener("skyhive:steps-changed", () => { window.stepsDrawn += 1; });
  window.fetch = async (url, options) => {
    if (String(url).includes("/check-envelope/") && window.holding) {
      await new Promise((go) => window.held.push(go));
    }
    return real(url, options);
  };
}"""


def confirm_while_the_area_is_computed_again(page, step_distance: str) -> None:  # type: ignore[no-untyped-def]
    """A coverage 1.5 km long (beyond the default distance), sent and confirmed; while the
    confirmed plan's check is on its way, the area is computed again with `step_distance`
    (as when a field the operator left loses focus), then the check answers."""
    page.wait_for_function("window.skyhivePlanner && window.skyhivePlanner.map")
    page.fill("#step-distance", "300")
    page.press("#step-distance", "Tab")
    corners = [point_at(100, 0), point_at(1500, 0), point_at(1500, 20)]
    page.evaluate(
        "(pts) => pts.forEach((p) => window.skyhivePlanner.map.fire('click', {latlng: L.latLng(p[0], p[1])}))",
        corners,
    )
    page.wait_for_function("window.skyhivePlanner.steps.length > 0")
    page.click("#send-mission")
    page.wait_for_selector("#beyond-defaults:not([hidden])")
    page.evaluate(HOLD_CHECKS)
    page.fill("#beyond-defaults-typed", "CONFIRM")
    page.click("#beyond-defaults-send")  # the confirmed plan's check starts, and is held
    page.wait_for_function("window.held.length > 0")
    page.fill("#step-distance", step_distance)
    page.evaluate("document.dispatchEvent(new CustomEvent('skyhive:survey-change'))")
    page.wait_for_function("window.stepsDrawn > 0")
    page.evaluate("window.releaseChecks()")


@pytest.fixture
def raised_planner(page, live_asgi, world_tx) -> None:  # type: ignore[no-untyped-def]
    """The planner, for an operator whose envelope is raised and whose drone is online."""
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope=RAISED)
    online_drone(world_tx.org, "ACME_1")
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")


def test_the_same_area_computed_again_during_the_confirmed_send_keeps_its_confirmation(
    page, raised_planner
):
    confirm_while_the_area_is_computed_again(page, "300")
    page.wait_for_url("**/missions/*-*/")
    assert Mission.objects.get().status == MissionStatus.RUNNING


def test_an_area_changed_during_the_confirmed_send_is_not_sent_on_the_old_confirmation(
    page, raised_planner
):
    confirm_while_the_area_is_computed_again(page, "200")
    page.wait_for_function(
        "document.querySelector('#planner-error').textContent.includes('plan changed')"
    )
    assert not Mission.objects.exists()
    page.click("#send-mission")  # the new plan goes beyond the defaults too: asked again
    page.wait_for_selector("#beyond-defaults:not([hidden])")
    assert not Mission.objects.exists()

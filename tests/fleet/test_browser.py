"""In a real browser: two simulated drones move on the fleet map; a command from the drone
page reaches the drone and shows its reply."""

from __future__ import annotations

import pytest
from django.db import connection

from fleet.models import Drone
from runtime.processes import wait_for

from .conftest import client_for
from .test_e2e import HEARTBEAT_S, IDS, start_fleet

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

PASSWORD = "correct horse battery staple"


def fly_north(user) -> None:  # type: ignore[no-untyped-def]
    operator = client_for(user)
    for drone_id in IDS:
        for params in (
            {"command": "arm"},
            {"command": "takeoff", "altitude": "3"},
            {"command": "changeN", "value": "30"},
        ):
            response = operator.post("/control", {"droneID": drone_id, **params})
            assert response.status_code == 200, response.content


def logged_commands(command: str, outcome: str | None = None) -> int:
    entries = Drone.objects.get(drone_id=IDS[0]).commands.filter(command=command)
    if outcome:
        entries = entries.filter(outcome=outcome, user__username="operator")
    return entries.count()


@pytest.fixture
def live_server_on_broker(broker):  # type: ignore[no-untyped-def]
    from tests.support.live import LiveServer

    server = LiveServer(
        connection.settings_dict["NAME"],
        extra_env={
            "MAP_TILE_URL": "",  # the test browser has no internet: plain background
            "MQTT_URL": broker.url_for("ground"),
            "MOSQUITTO_DIR": str(broker.directory),
        },
    )
    yield server
    server.stop()


def test_an_operator_watches_two_drones_move_and_commands_one(
    world_tx, broker, gateway, live_server_on_broker, page, tmp_path, settings
):
    settings.HEARTBEAT_INTERVAL_S = HEARTBEAT_S
    settings.FLEET_PUSH_INTERVAL_S = 0.2
    fleet = start_fleet(tmp_path, broker.port)
    try:
        assert wait_for(
            lambda: Drone.objects.filter(drone_id__in=IDS, online=True).count() == 2, 30
        )
        url = live_server_on_broker.url
        page.goto(f"{url}/accounts/login/")
        page.fill("input[name=username]", "operator")
        page.fill("input[name=password]", PASSWORD)
        page.click("button[type=submit]")
        page.wait_for_url(f"{url}/")
        page.wait_for_function(
            "window.skyhiveFleet && window.skyhiveFleet.markerIds().length === 2", timeout=10_000
        )
        page.wait_for_selector("#live-status.ok")
        start = {i: page.evaluate(f"window.skyhiveFleet.markerPosition('{i}')") for i in IDS}

        fly_north(world_tx.operator)

        for drone_id in IDS:
            page.wait_for_function(
                """([id, lat]) => {
                    const p = window.skyhiveFleet.markerPosition(id);
                    return p && p.lat - lat > 0.0001;
                }""",
                arg=[drone_id, start[drone_id]["lat"]],
                timeout=15_000,
            )
        row = page.locator(f'#drone-table tr[data-drone="{IDS[0]}"] [data-field="state"]')
        assert row.inner_text() == "airborne"

        page.goto(f"{url}/drones/{IDS[0]}/")
        page.fill('form[data-command="changeE"] input[name=value]', "10")
        page.click('form[data-command="changeE"] button')
        page.wait_for_selector('#command-result[data-status="ok"]', timeout=15_000)
        assert page.inner_text("#command-result").startswith("changeE: ok")
        # The log entry is written once the answer has been sent (fleet.commands.execute's
        # after_answer): 1.3-2.5 ms after it (docs/performance.md), so the page may show the
        # reply first; 10 s is for a loaded machine.
        assert wait_for(lambda: logged_commands("changeE", "ok") == 1, 10)

        # A destructive command asks first; dismissing sends nothing.
        page.once("dialog", lambda dialog: dialog.dismiss())
        page.click('form[data-command="disarm"] button')
        page.wait_for_timeout(300)
        assert logged_commands("disarm") == 0
    finally:
        fleet.stop()

"""End to end: an operator's log collection mode reaches a simulated drone (the simulator
and the real onboard agent, on a real ground over a private Mosquitto). Turned off on the
drone's page (headless Chromium), a flight leaves nothing on the ground; turned back on
through the API, the next flight's log arrives, and only that one."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace

import pytest
from playwright.sync_api import expect

from tests.conftest import login
from tests.logs.test_collection_e2e import ENV, _drone, _fly, _start
from tests.support.ground import Api, mosquitto_ground, wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.browser, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_LOGPOL"


def _mode_on_board(folder: Path) -> str | None:
    """The mode the agent keeps across restarts (onboard/collect.py GroundMode)."""
    try:
        return json.loads((folder / "logs" / "collect-policy.json").read_text())["log_collection"]
    except (OSError, ValueError, KeyError):
        return None


def _collected() -> list:
    from logs.models import CollectedLog

    return list(CollectedLog.objects.filter(drone__drone_id=DRONE))


def test_off_on_the_page_uploads_nothing_and_always_through_the_api_uploads_the_next_flight(
    world_tx, tmp_path, settings, page
):
    with mosquitto_ground(
        tmp_path, settings, web=1, gateways=1, ingests=1, workers=1, env=ENV
    ) as ground:
        _start(ground, DRONE, world_tx.org.slug, "uavtalk", 0.0)
        ground.wait_online([DRONE])
        folder = ground.directory / DRONE
        assert wait_for(lambda: _mode_on_board(folder) == "always", 30)

        web = ground.processes.web_urls[0]
        login(page, SimpleNamespace(url=web), "operator")
        page.goto(f"{web}/drones/{DRONE}/")
        form = page.locator("#log-collection-form")
        form.locator("select[name=log_collection]").select_option("off")
        form.locator("button[type=submit]").click()
        expect(page.locator("[data-log-collection]")).to_have_attribute(
            "data-log-collection", "off"
        )
        assert wait_for(lambda: _mode_on_board(folder) == "off", 30)

        api = Api(world_tx.operator, ground.processes.web_urls)
        _fly(api, DRONE)
        first_landed = datetime.now(UTC)
        refused = Api(world_tx.viewer, ground.processes.web_urls).request(
            "PUT", f"/api/v1/logs/collection/{DRONE}/", {"log_collection": "always"}
        )
        assert refused.status_code == 403, refused.text
        answer = api.request(
            "PUT", f"/api/v1/logs/collection/{DRONE}/", {"log_collection": "always"}
        )
        assert answer.status_code == 200, answer.text
        assert wait_for(lambda: _mode_on_board(folder) == "always", 30)
        assert _collected() == []  # the flight flown while off left nothing to send

        _fly(api, DRONE)
        assert wait_for(lambda: len(_collected()) == 1 and _collected()[0].completed_at, 90)
        wait_for(lambda: len(_collected()) > 1, 5)  # a late upload of the first would show

    logs = _collected()
    assert len(logs) == 1, [(c.name, c.flight_started_at) for c in logs]
    assert logs[0].kind == "onboard" and logs[0].flight_started_at > first_landed
    assert _drone(DRONE).log_collection == "always"

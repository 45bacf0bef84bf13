"""Operator controls through the commands API: hold, return and land reach the drone in one
request each; viewers may not send them; they are not mission steps."""

from __future__ import annotations

import pytest

from fleet.models import CommandLog
from onboard import protocol

from .conftest import client_for
from .test_commands import online  # noqa: F401  (fixture)

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.mark.parametrize("command", ["hold", "return", "land"])
def test_hold_return_and_land_reach_the_drone_and_are_logged(world_tx, online, command):  # noqa: F811
    response = client_for(world_tx.operator).post(
        "/api/v1/drones/ACME_1/commands/", {"command": command}, content_type="application/json"
    )
    assert response.status_code == 200, response.content
    assert response.json()["ok"] is True
    assert [(r["command"], r["params"]) for r in online.requests] == [(command, {})]
    entry = CommandLog.objects.get(request_id=response.json()["request_id"])
    assert (entry.command, entry.outcome) == (command, "ok")


def test_a_viewer_cannot_hold_or_return_a_drone_and_nothing_is_sent(world_tx, online):  # noqa: F811
    for command in ("hold", "return"):
        response = client_for(world_tx.viewer).post(
            "/api/v1/drones/ACME_1/commands/",
            {"command": command},
            content_type="application/json",
        )
        assert response.status_code == 403
    assert online.requests == []


def test_hold_and_return_are_not_mission_steps() -> None:
    for command in ("hold", "return"):
        protocol.validate_command(command)
        with pytest.raises(protocol.ProtocolError, match="unknown command"):
            protocol.validate_command(command, mission=True)

"""The ground's side of the drones' fail-safe: acknowledging alarms."""

from __future__ import annotations

import pytest

from missions.alarms import apply_alarm
from missions.services import create_mission, start_mission
from onboard import protocol

from .conftest import online_drone

pytestmark = pytest.mark.django_db


def _steps() -> list[dict]:
    return [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10}}]


@pytest.mark.parametrize(("level", "acked"), [("CRITICAL", True), ("OUT_MEASURE", False)])
def test_a_critical_alarm_is_acknowledged_to_the_drone_at_once(
    world, outbox, level: str, acked: bool
) -> None:
    drone = online_drone(world.org, "ACME_A")
    mission = create_mission(organisation=world.org, name="x", steps=_steps())
    assignment = start_mission(mission, drone=drone).assignment
    outbox.clear()
    alarm = protocol.Alarm(
        level, "battery below 25 %", None, str(mission.pk), str(assignment.pk), 1
    )
    apply_alarm(drone, alarm)
    acks = [i for i in outbox.items() if i["topic"] == "ACME_A/alarms/in"]
    assert [protocol.parse_alarm_ack(i["payload"]).level for i in acks] == (
        ["CRITICAL"] if acked else []
    )


@pytest.mark.parametrize(("ahead", "trusted"), [(0.3, True), (3600.0, False)])
@pytest.mark.django_db(False)
def test_a_drone_clock_far_from_the_grounds_is_shown_untrusted(ahead: float, trusted: bool) -> None:
    from datetime import UTC, datetime

    from fleet.heartbeats import fc_state

    seen = datetime(2026, 1, 1, tzinfo=UTC)
    beat = protocol.Heartbeat(
        "ACME_A", seen.timestamp() + ahead, None, None, None, False, False, "", None, "fake", True
    )
    state = fc_state(beat, seen)
    assert state["clock_offset_s"] == pytest.approx(ahead) and state["clock_trusted"] is trusted

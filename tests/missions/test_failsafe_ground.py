"""The ground's side of the drones' fail-safe: acknowledging alarms."""

from __future__ import annotations

import pytest

from missions.alarms import apply_alarm
from missions.creation import create_mission
from missions.startstop import start_mission
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


def _survey(world, drone) -> tuple:  # type: ignore[no-untyped-def]
    from missions.planning import mission_steps

    from .conftest import point_at

    points = [point_at(10.0 * i, 0.0) for i in range(3)]
    mission = create_mission(
        organisation=world.org, name="s", steps=mission_steps(points, altitude=10)
    )
    return mission, start_mission(mission, drone=drone).assignment


def _went_offline(drone) -> list[str]:  # type: ignore[no-untyped-def]
    from datetime import timedelta

    from django.utils import timezone

    from fleet.heartbeats import sweep_offline

    type(drone).objects.filter(pk=drone.pk).update(
        last_seen=timezone.now() - timedelta(seconds=120)
    )
    return sweep_offline()


@pytest.mark.parametrize("comes_back", [False, True], ids=["still-offline", "back-in-time"])
def test_a_drone_offline_mid_mission_shows_at_once_and_is_replaced_after_the_grace(
    world, outbox, comes_back: bool
) -> None:
    from missions.models import Assignment, Event
    from missions.offline import replace_if_still_offline

    flying = online_drone(world.org, "ACME_A", north=15)
    online_drone(world.org, "ACME_B", north=40)
    mission, assignment = _survey(world, flying)
    assert _went_offline(flying) == ["ACME_A"]
    shown = mission.events.get(kind=Event.Kind.DECISION, data__decision="offline")
    assert "ACME_A went offline mid-mission" in shown.message
    assert shown.data["position"]["lat"] == pytest.approx(flying.lat)
    if comes_back:
        type(flying).objects.filter(pk=flying.pk).update(online=True)
    replace_if_still_offline(str(mission.pk), str(assignment.pk), shown.pk)
    replaced = mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT)
    if comes_back:
        assert not replaced.exists()
        assert mission.events.filter(data__decision="offline_back").exists()
    else:
        assert replaced.get().drone.drone_id == "ACME_B"
        assignment.refresh_from_db()
        assert assignment.status == Assignment.Status.STOPPED


def test_a_drone_offline_outside_a_mission_changes_no_mission(world, outbox) -> None:
    from missions.models import Event

    idle = online_drone(world.org, "ACME_A")
    assert _went_offline(idle) == ["ACME_A"]
    assert not Event.objects.filter(data__decision="offline").exists()


@pytest.mark.parametrize(("offset", "shown"), [(0.2, False), (-3600.0, True)])
def test_the_drone_page_shows_a_clock_it_cannot_trust(world, offset: float, shown: bool) -> None:
    from django.test import Client

    from fleet.models import Drone

    Drone.objects.filter(drone_id="ACME_1").update(
        fc={"protocol": "uavtalk", "connected": True, "clock_offset_s": offset,
            "clock_trusted": abs(offset) <= 5}
    )  # fmt: skip
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/drones/ACME_1/").content.decode()
    assert f"{offset} s from the ground" in html.replace("&#x27;", "'")
    assert ("not trusted" in html) is shown


def test_a_panic_drone_down_to_the_reserve_on_station_is_relieved_once(world, outbox) -> None:
    from fleet.models import Drone
    from missions import panic
    from missions.models import Assignment

    from .conftest import point_at

    online_drone(world.org, "ACME_A", north=10)
    online_drone(world.org, "ACME_B", north=200)
    lat, lon = point_at(0, 0)
    call = panic.call_drone(organisation=world.org, lat=lat, lon=lon).mission
    assert panic.relieve_stations() == []  # a full battery stays on station
    Drone.objects.filter(drone_id="ACME_A").update(battery_remaining=0.2)
    assert panic.relieve_stations() == ["ACME_A"]
    relief = call.assignments.get(reason=Assignment.Reason.REPLACEMENT)
    assert relief.drone.drone_id == "ACME_B"
    station = [call.steps.get(index=i).command for i in relief.step_indexes]
    assert station[-1] == "sleep"  # the station itself is handed over
    assert panic.relieve_stations() == []  # once

"""Due maintenance keeps a drone on the ground: counted from the flight records by hours,
flights or days; an overdue drone is passed over for a replacement (the next nearest
goes) and its manual arm refused with 409 `not_airworthy` naming the task, until an admin
signs it off."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.utils import timezone

from fleet import commands
from fleet.models import CommandLog, Drone
from maintenance import due
from maintenance.models import Schedule
from missions import replacement
from missions.creation import create_mission
from missions.startstop import start_mission
from tests.missions.conftest import online_drone, outbox  # noqa: F401 (fixture)
from tests.missions.test_services import _alarm_event, _complete, _steps

from .support import api, flown

pytestmark = pytest.mark.django_db


def _schedule(drone: Drone, **every: float) -> Schedule:
    return Schedule.objects.create(
        organisation_id=drone.organisation_id, drone=drone, name="Motor replacement", **every
    )


def test_hours_flights_and_days_count_from_the_records_with_a_due_soon_margin(world, settings):
    settings.MAINTENANCE_DUE_SOON_FRACTION = 0.1
    flown(world.drone, minutes=30, count=3)  # 1.5 h in 3 flights
    hours = _schedule(world.drone, every_hours=1.6)
    (item,) = due.items(world.drone)
    assert (item.status, item.measures[0].used) == (due.DUE_SOON, pytest.approx(1.5))
    Schedule.objects.filter(pk=hours.pk).update(every_hours=1.0)
    (item,) = due.items(world.drone)
    assert item.status == due.DUE and item.overdue == "overdue by 0.5 flight hours (interval 1)"
    Schedule.objects.filter(pk=hours.pk).update(every_hours=None, every_flights=10)
    assert due.items(world.drone)[0].status == due.OK
    Drone.objects.filter(pk=world.drone.pk).update(created_at=timezone.now() - timedelta(days=400))
    world.drone.refresh_from_db()
    Schedule.objects.filter(pk=hours.pk).update(every_days=365)
    assert due.items(world.drone)[0].overdue.startswith("overdue by 35 days")


def test_an_overdue_drone_is_not_picked_as_a_replacement_the_next_nearest_is(
    world,
    outbox,  # noqa: F811
):
    first = online_drone(world.org, "ACME_A")
    near = online_drone(world.org, "ACME_B", north=50)
    online_drone(world.org, "ACME_C", north=300)
    flown(near, minutes=10, count=2)
    _schedule(near, every_flights=2)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2, 3])
    alarm = _alarm_event(mission, first)
    replacing = replacement.replace_drone(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    assert replacing is not None and replacing.drone.drone_id == "ACME_C"


def test_an_overdue_drone_may_not_arm_until_an_admin_signs_the_task_off(world, outbox):  # noqa: F811
    drone = online_drone(world.org, "ACME_1")
    flown(drone, minutes=45, count=2)
    schedule = _schedule(drone, every_hours=1.0)
    refused = api(world.operator).post(
        "/api/v1/drones/ACME_1/commands/", {"command": "arm", "params": {}}, format="json"
    )
    assert refused.status_code == 409
    body = refused.json()
    assert body["code"] == "not_airworthy"
    assert "maintenance due: 'Motor replacement' overdue by 0.5 flight hours" in body["error"]
    assert CommandLog.objects.get().outcome == CommandLog.Outcome.REJECTED
    assert outbox.items() == []

    signed = api(world.owner).post(
        "/api/v1/drones/ACME_1/maintenance/log/",
        {"schedule": schedule.pk, "notes": "four motors replaced", "parts": ["motor"] * 4},
        format="json",
    )
    assert signed.status_code == 201
    (item,) = due.items(drone)
    assert item.status == due.OK and item.measures[0].used == 0
    # Every ground check of an arm passes now (the drone's reply is the flight's business).
    prepared = commands.prepare(world.operator, "ACME_1", "arm", {})
    assert prepared.command == "arm"
    verdict = api(world.viewer).get("/api/v1/drones/ACME_1/airworthiness/").json()
    assert verdict == {"airworthy": True, "reasons": []}

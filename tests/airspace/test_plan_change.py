"""A reservation ends when its drone's plan changes: a navigation command the drone
accepted in the middle of a mission replaces the mission's corridors with its own leg, so
the corridor it left no longer blocks another drone."""

from __future__ import annotations

import pytest

from airspace import reservations
from airspace.models import Reservation
from fleet.models import Drone
from tests.missions.conftest import point_at

from .test_separation import crossing, start, two_drones  # noqa: F401

pytestmark = pytest.mark.django_db


def test_a_new_plan_ends_the_previous_reservation_and_frees_its_corridor(two_drones):  # noqa: F811
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    blocked = start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B")
    assert blocked.status_code == 409 and "drone ACME_A" in blocked.json()["error"]

    # ACME_A, climbing out of its home, is sent south-east, away from the crossing.
    here = point_at(-150, 0)
    Drone.objects.filter(drone_id="ACME_A").update(
        airborne=True, alt=20.0, home=list(here), lat=here[0], lon=here[1]
    )
    away = point_at(-300, 150)
    reservations.reserve_command(
        Drone.objects.get(drone_id="ACME_A"), "navigate", {"lat": away[0], "lon": away[1]}
    )
    mission, command = Reservation.objects.order_by("pk")
    assert (mission.kind, mission.end_reason) == ("mission", "replaced by a new plan")
    assert mission.ended_at is not None
    assert (command.kind, command.ended_at) == ("command", None)

    crossing_now = start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B")
    assert crossing_now.status_code == 200, crossing_now.json()

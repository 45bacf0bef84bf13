"""Live separation: two drones predicted within the minima in the next seconds from
their reported positions and velocities; the one with the newer (or no) reservation is
held and a CRITICAL alert raised, once per pair."""

from __future__ import annotations

import time

import pytest
from django.core.cache import cache

from airspace import live
from airspace.models import Reservation
from alerts.models import Alert
from fleet.models import Drone
from tests.missions.conftest import online_drone, point_at

pytestmark = pytest.mark.django_db


def track(drone_id: str, x: float, y: float, z: float, vx: float = 0.0, vy: float = 0.0):  # type: ignore[no-untyped-def]
    return live.Track(drone_id, x, y, z, vx, vy, 0.0, 30.0, 10.0)


def test_head_on_at_one_height_is_predicted_when_they_come_within_the_minimum():
    a, b = track("A", 0, 0, 20, vx=5), track("B", 100, 0, 20, vx=-5)
    (loss,) = live.predicted_losses([a, b], horizon_s=10, step_s=0.5)
    # 100 m apart closing at 10 m/s: below 30 m after 7 s (at 7.5 s on the 0.5 s steps).
    assert loss.in_s == 7.5 and loss.horizontal_m < 30
    assert live.predicted_losses([a, track("B", 100, 0, 40, vx=-5)], 10, 0.5) == []
    assert live.predicted_losses([a, track("B", 100, 0, 20, vx=5)], 10, 0.5) == []
    assert live.predicted_losses([a, track("B", 200, 0, 20, vx=-5)], 10, 0.5) == []


def _fly(drone: Drone, north: float) -> None:
    lat, lon = point_at(north, 0)
    Drone.objects.filter(pk=drone.pk).update(lat=lat, lon=lon, alt=20.0, airborne=True)


def test_the_drone_without_a_reservation_is_held_with_a_critical_alert(world, outbox, settings):
    # The velocities come from two looks about 0.5 s apart (5 m each: closing at 20 m/s);
    # a minute's horizon still predicts the loss if a loaded machine makes that 7 s.
    settings.AIRSPACE_LIVE_HORIZON_S = 60.0
    first = online_drone(world.org, "ACME_A")
    second = online_drone(world.org, "ACME_B")
    for drone_id in ("ACME_A", "ACME_B"):
        cache.delete(live._FIX_KEY.format(drone_id))
        cache.delete(live._HELD_KEY.format("ACME_A", "ACME_B"))
    _fly(first, -60)
    _fly(second, 60)
    Reservation.objects.create(
        organisation=world.org, drone=first, kind="command", legs=[[*point_at(-60, 0),
        *point_at(-60, 0), 0, 22, 0, 4e9]], starts_at="2026-01-01T00:00Z",
        ends_at="2099-01-01T00:00Z", airborne_by="2026-01-01T00:00Z", radius_m=2,
        horizontal_min_m=30, vertical_min_m=10, min_lat=0, max_lat=0, min_lon=0, max_lon=0,
    )  # fmt: skip
    assert live.watch() == []  # no velocity known yet: 120 m apart, still
    time.sleep(0.5)
    _fly(first, -55)  # 10 m/s north
    _fly(second, 55)  # 10 m/s south: 110 m apart, closing at about 20 m/s
    assert live.watch() == ["ACME_B"]
    sent_b = [item for item in outbox.items() if item["topic"].startswith("ACME_B/")]
    (sent,) = [item for item in sent_b if item["topic"] != "ACME_B/traffic/in"]
    assert sent["topic"] == "ACME_B/control/in" and sent["payload"]["command"] == "navigate"
    alert = Alert.objects.get(drone_id="ACME_B")
    assert alert.severity == "critical" and "ACME_A" in alert.title
    # Once per pair: the next look holds nobody again.
    time.sleep(0.2)
    assert live.watch() == []

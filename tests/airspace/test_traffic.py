"""The traffic relay: each live-separation pass tells every airborne drone the other
airborne drones of its airspace within range (the nearest, at most AIRSPACE_TRAFFIC_MAX)
and its reservation's band on `<id>/traffic/in`, QoS 0, in the message the agent parses;
with the ground's own hold switched off nobody is held but traffic is still relayed."""

from __future__ import annotations

import time

import pytest
from django.core.cache import cache

from airspace import live
from airspace.models import Reservation
from fleet.models import Drone
from onboard.traffic import parse_traffic
from tests.factories import organisation
from tests.missions.conftest import online_drone, point_at

pytestmark = pytest.mark.django_db


def _fly(drone: Drone, north: float, alt: float = 20.0) -> None:
    lat, lon = point_at(north, 0)
    Drone.objects.filter(pk=drone.pk).update(lat=lat, lon=lon, alt=alt, airborne=True)


def _reserve(org, drone: Drone, low: float, high: float) -> None:  # type: ignore[no-untyped-def]
    Reservation.objects.create(
        organisation=org, drone=drone, kind="command", legs=[[*point_at(-60, 0),
        *point_at(-60, 0), low, high, 0, 4e9]], starts_at="2026-01-01T00:00Z",
        ends_at="2099-01-01T00:00Z", airborne_by="2026-01-01T00:00Z", radius_m=2,
        horizontal_min_m=30, vertical_min_m=10, min_lat=0, max_lat=0, min_lon=0, max_lon=0,
    )  # fmt: skip


def _traffic(outbox, drone_id: str) -> list[dict]:  # type: ignore[no-untyped-def]
    return [i for i in outbox.items() if i["topic"] == f"{drone_id}/traffic/in"]


def test_each_airborne_drone_gets_its_nearest_neighbours_and_band(world, outbox, settings):
    settings.AIRSPACE_TRAFFIC_MAX = 2
    settings.AIRSPACE_TRAFFIC_RANGE_M = 500.0
    ids = ["ACME_A", "ACME_B", "ACME_C", "ACME_D", "ACME_E"]
    norths = [0, 40, 80, 120, 900]  # ACME_E is beyond range of all
    drones = [online_drone(world.org, d) for d in ids]
    for drone, north in zip(drones, norths, strict=True):
        cache.delete(live._FIX_KEY.format(drone.drone_id))
        _fly(drone, north)
    _reserve(world.org, drones[0], 15, 25)
    live.watch()  # remembers the first fixes
    outbox.clear()
    time.sleep(0.3)
    _fly(drones[1], 43)  # 3 m north in at least 0.3 s: at most 10 m/s
    settings.AIRSPACE_LIVE_HOLD = False
    assert live.watch() == []
    (to_a,) = _traffic(outbox, "ACME_A")
    assert to_a["qos"] == 0
    update = parse_traffic(to_a["payload"])
    assert update.band == (15.0, 25.0)
    assert [o.drone_id for o in update.others] == ["ACME_B", "ACME_C"]  # nearest two
    b = update.others[0]
    assert 0 < b.vn <= 10.1 and b.ve == pytest.approx(0, abs=0.01) and b.alt == 20.0
    assert (b.horizontal_min_m, b.vertical_min_m) == (30.0, 10.0)
    (to_e,) = _traffic(outbox, "ACME_E")
    assert parse_traffic(to_e["payload"]).others == () and to_e["payload"]["band"] is None
    # Only traffic was sent: with the ground's hold off nobody is told to hold.
    assert {i["topic"].split("/")[1] for i in outbox.items()} == {"traffic"}


def test_drones_of_another_organisation_are_not_relayed(world, outbox):
    mine = online_drone(world.org, "ACME_A")
    theirs = online_drone(organisation("other"), "OTHER_A")
    _fly(mine, 0)
    _fly(theirs, 20)
    live.watch()
    (to_mine,) = _traffic(outbox, "ACME_A")
    assert parse_traffic(to_mine["payload"]).others == ()


def test_both_brokers_let_a_drone_read_its_own_traffic_only():
    import re

    from workers.broker.credentials import rabbitmq_definitions
    from workers.mosquitto import GROUND_AND_DRONES_ACL

    (permission,) = rabbitmq_definitions([("ACME_A", "hash")])["topic_permissions"]
    assert re.match(permission["read"], "ACME_A.traffic.in")
    assert not re.match(permission["read"], "ACME_B.traffic.in")
    assert not re.match(permission["write"], "ACME_A.traffic.in")
    # Mosquitto: the pattern the drones' ACL reads by (the e2e tests subscribe through it).
    assert "pattern read %u/+/in" in GROUND_AND_DRONES_ACL

"""The landing queue's decisions on the real database (airspace/landing.py): a drone sent
home to a free site goes home as before; to a busy one it holds over home at a clear
layer; the queue lands one drone at a time, first come first served, never one through
another; a drone that lands elsewhere, goes offline or is given another plan leaves it."""

from __future__ import annotations

import pytest

from airspace import landing, reservations, separation
from airspace.models import LandingSlot, Reservation
from fleet.models import Drone
from tests.missions.conftest import online_drone, point_at

from .scenes import failing_over_origin, replace

pytestmark = pytest.mark.django_db


def flying(org, drone_id: str, height: float, north: float = 0.0, east: float = 0.0) -> Drone:  # type: ignore[no-untyped-def]
    """A drone in the air `height` metres over its home, `north`/`east` of the origin."""
    drone = online_drone(org, drone_id, north=north, east=east)
    Drone.objects.filter(pk=drone.pk).update(
        airborne=True, armed=True, alt=height, home=[drone.lat, drone.lon]
    )
    drone.refresh_from_db()
    return drone


def on_ground(drone: Drone, north: float | None = None) -> None:
    fields: dict = {"airborne": False, "alt": 0.0}
    if north is not None:
        fields["lat"], fields["lon"] = point_at(north, 0.0)
    Drone.objects.filter(pk=drone.pk).update(**fields)


def lands_sent(outbox) -> list[str]:  # type: ignore[no-untyped-def]
    return [
        item["topic"].split("/")[0]
        for item in outbox.items()
        if item["topic"].endswith("/control/in") and item["payload"]["command"] == "land"
    ]


def advance(capture) -> list[str]:  # type: ignore[no-untyped-def]
    with capture(execute=True):
        return landing.advance()


def test_holding_layer_is_the_lowest_clear_one_at_or_above_the_height_under_the_ceiling():
    assert landing.holding_layer(30.0, [], 14.0, 10.0, 120.0) == 30.0
    assert landing.holding_layer(30.0, [24.0, 38.0], 14.0, 10.0, 120.0) == 58.0
    assert landing.holding_layer(30.0, [16.0, 44.0], 14.0, 10.0, 120.0) == 30.0
    # No clear layer under the ceiling: it holds where it is.
    assert landing.holding_layer(100.0, [100.0, 114.0], 14.0, 10.0, 120.0) == 100.0
    # Over the site it never climbs through another drone's height.
    assert landing.holding_layer(30.0, [24.0, 38.0], 14.0, 10.0, 120.0, True) == 30.0
    assert landing.holding_layer(30.0, [24.0], 14.0, 10.0, 120.0, True) == 44.0


def test_a_drone_sent_home_to_a_free_site_goes_home_as_before(world):
    a = flying(world.org, "ACME_A", 40.0)
    flying(world.org, "ACME_B", 40.0, north=200.0)  # another site
    assert landing.send_home(a) is None
    slot = LandingSlot.objects.get(drone=a, ended_at__isnull=True)
    assert slot.state == LandingSlot.State.LANDING and slot.layer_m == 40.0
    reserved = Reservation.objects.get(drone=a, ended_at__isnull=True)
    assert reserved.command == reservations.LANDING_QUEUE
    # Its way down reaches the ground at home.
    assert min(leg[4] for leg in reserved.legs) == 0.0


def test_a_busy_site_queues_the_drone_over_home_at_a_clear_layer(world):
    low = flying(world.org, "ACME_L", 24.0, east=3.0)
    high = flying(world.org, "ACME_H", 30.0)
    queued = landing.send_home(high)
    # ACME_L is in the air below it over the site: it must not come down through it.
    assert queued is not None and queued.place == 1
    assert queued.layer_m == 44.0  # 30 m is within 10 m of ACME_L's 24 m; 30 + 14 is clear
    command, params = landing.hold_command(high, queued)
    assert command == "navigate" and params["altitude_delta"] == pytest.approx(14.0)
    # The hold is the queue's own: not refused against the queue's reservations.
    separation.check_command(high, command, params)
    second = landing.send_home(low)
    assert second is not None and second.place == 2 and second.layer_m == 24.0


def test_every_drone_after_the_first_queues_at_a_layer_of_its_own(world):
    top = flying(world.org, "ACME_T", 52.0)
    mid = flying(world.org, "ACME_M", 38.0, east=2.0)
    low = flying(world.org, "ACME_W", 10.0, north=2.0)
    for drone in (mid, top, low):
        landing.send_home(drone)
    slots = landing.queue_of(world.org)
    assert [s.drone.drone_id for s in slots] == ["ACME_M", "ACME_T", "ACME_W"]
    assert all(s.state == LandingSlot.State.HOLDING for s in slots)


def test_turns_go_to_the_first_arrival_with_nothing_under_it(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    capture = django_capture_on_commit_callbacks
    top = flying(world.org, "ACME_T", 52.0)
    mid = flying(world.org, "ACME_M", 38.0, east=2.0)
    low = flying(world.org, "ACME_W", 24.0, north=2.0)
    for drone in (top, mid, low):
        assert landing.send_home(drone) is not None
    # ACME_T came first but ACME_M and ACME_W are under it, ACME_M has ACME_W under it:
    # ACME_W, with nothing under it, lands first.
    assert advance(capture) == ["ACME_W"]
    # One at a time: the others wait while ACME_W comes down.
    assert advance(capture) == []
    on_ground(low)
    assert advance(capture) == ["ACME_M"]
    assert LandingSlot.objects.get(drone=low).end_reason == "landed"
    assert advance(capture) == []
    on_ground(mid)
    assert advance(capture) == ["ACME_T"]
    assert lands_sent(outbox) == ["ACME_W", "ACME_M", "ACME_T"]
    landing_row = Reservation.objects.get(drone=top, ended_at__isnull=True)
    assert landing_row.command == reservations.LANDING_QUEUE


def test_first_come_first_served_between_drones_with_nothing_under_them(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    capture = django_capture_on_commit_callbacks
    blocker = flying(world.org, "ACME_X", 20.0)
    a = flying(world.org, "ACME_A", 48.0, east=2.0)
    b = flying(world.org, "ACME_B", 34.0, north=2.0)
    landing.send_home(b)
    landing.send_home(a)
    # ACME_X hovers under both (not queued): nobody may come down.
    assert advance(capture) == []
    Drone.objects.filter(pk=blocker.pk).update(lat=point_at(300.0, 0.0)[0])
    assert advance(capture) == ["ACME_B"]


def test_a_drone_that_went_away_never_stalls_the_queue(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    capture = django_capture_on_commit_callbacks
    low = flying(world.org, "ACME_W", 10.0)
    high = flying(world.org, "ACME_H", 24.0, east=2.0)
    landing.send_home(low)  # free: home as before, landing
    assert landing.send_home(high) is not None
    assert advance(capture) == []
    Drone.objects.filter(pk=low.pk).update(online=False)
    assert advance(capture) == ["ACME_H"]
    assert LandingSlot.objects.get(drone=low).end_reason == "disconnected"


def test_a_drone_landing_elsewhere_or_commanded_otherwise_leaves_the_queue(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    capture = django_capture_on_commit_callbacks
    low = flying(world.org, "ACME_W", 10.0)
    mid = flying(world.org, "ACME_M", 24.0, east=2.0)
    high = flying(world.org, "ACME_H", 38.0, north=2.0)
    for drone in (low, mid, high):
        landing.send_home(drone)
    on_ground(low, north=500.0)
    # The operator sends ACME_M elsewhere: another plan.
    elsewhere = point_at(200.0, 0.0)
    reservations.reserve_command(
        mid, "navigate", {"lat": elsewhere[0], "lon": elsewhere[1], "altitude_delta": 0.0}
    )
    Drone.objects.filter(pk=mid.pk).update(lat=elsewhere[0], lon=elsewhere[1])
    assert advance(capture) == ["ACME_H"]
    ended = dict(LandingSlot.objects.values_list("drone__drone_id", "end_reason"))
    assert ended["ACME_W"] == "landed elsewhere"
    assert ended["ACME_M"] == "commanded otherwise"


def test_a_holding_drone_not_yet_over_home_waits_for_its_hold(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    capture = django_capture_on_commit_callbacks
    below = flying(world.org, "ACME_W", 10.0)
    away = flying(world.org, "ACME_F", 40.0, east=2.0)
    assert landing.send_home(away) is not None
    Drone.objects.filter(pk=below.pk).update(lat=point_at(300.0, 0.0)[0])
    Drone.objects.filter(pk=away.pk).update(lat=point_at(20.0, 0.0)[0])
    assert advance(capture) == []
    Drone.objects.filter(pk=away.pk).update(lat=point_at(1.0, 2.0)[0], lon=point_at(1.0, 2.0)[1])
    assert advance(capture) == ["ACME_F"]


def test_the_return_route_answers_the_queue_or_nothing(world):
    top = flying(world.org, "ACME_T", 52.0)
    flying(world.org, "ACME_W", 24.0, north=2.0)
    routed = landing.route_return(top)
    assert routed is not None
    command, params, queue = routed
    assert command == "navigate" and queue == {
        "place": 1,
        "layer_m": 52.0,
        "site": [top.home[0], top.home[1]],
    }
    # Its hold unanswered, it keeps its place (the queue sends the hold again if need be).
    landing.return_answered(top, "return", None)
    assert LandingSlot.objects.get(drone=top).ended_at is None
    alone = flying(world.org, "ACME_Z", 30.0, north=400.0)
    assert landing.route_return(alone) is None
    # A return sent as before and unanswered leaves: the site is not kept for it.
    landing.return_answered(alone, "return", None)
    assert LandingSlot.objects.get(drone=alone).end_reason == "no answer to the return"


def test_other_organisations_queues_are_their_own(world):
    mine = flying(world.org, "ACME_A", 40.0)
    theirs = flying(world.other_org, "OTHER_A", 10.0, east=2.0)
    assert landing.send_home(theirs) is None
    assert landing.send_home(mine) is None


def _clear_of(flight_row: Reservation, other: Reservation) -> bool:
    from airspace.corridors import Leg
    from airspace.index import Airspace, Flight

    legs = [Leg.from_list(leg) for leg in flight_row.legs]
    flight = Flight(legs, flight_row.radius_m, 30.0, 10.0)
    return Airspace([reservations._reserved(other)]).first_conflict(flight) is None


def test_a_replacement_flying_to_a_drone_still_returning_home_keeps_clear_of_it(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    failing, mission, assignment, alarm = failing_over_origin(world, -20.0, with_home=True)
    with django_capture_on_commit_callbacks(execute=True):
        replacing = replace(mission, assignment, alarm, then="return")
    assert replacing is not None and replacing.drone.drone_id == "ACME_B"
    # Its site is free: it goes home as before (the stop's `then`), counted as landing.
    slot = LandingSlot.objects.get(drone=failing, ended_at__isnull=True)
    assert slot.state == LandingSlot.State.LANDING
    stops = [i["payload"] for i in outbox.items() if i["topic"] == "ACME_A/mission/in"]
    assert [s["then"] for s in stops if "then" in s] == ["return"]
    returning = Reservation.objects.get(drone=failing, ended_at__isnull=True)
    assert returning.command == reservations.LANDING_QUEUE
    flying_in = Reservation.objects.get(assignment=replacing, ended_at__isnull=True)
    assert _clear_of(flying_in, returning)


def test_a_stopped_drone_whose_home_is_busy_holds_over_it_and_keeps_the_replacement_clear(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    failing, mission, assignment, alarm = failing_over_origin(world, -20.0, with_home=True)
    # Another drone is landing at a home 25 m from ACME_A's: the same site.
    other = flying(world.org, "ACME_C", 5.0, north=-45.0)
    Drone.objects.filter(pk=other.pk).update(battery_remaining=0.1)  # no replacement
    assert landing.send_home(other) is None
    with django_capture_on_commit_callbacks(execute=True):
        replacing = replace(mission, assignment, alarm, then="return")
    assert replacing is not None and replacing.drone.drone_id == "ACME_B"
    slot = LandingSlot.objects.get(drone=failing, ended_at__isnull=True)
    assert slot.state == LandingSlot.State.HOLDING
    # ACME_C is landing at 5 m: ACME_A's 10 m is within the minimum, so one layer up.
    assert slot.layer_m == 24.0
    # Stopped where it is; its hold is not sent with the stop (whose own hold where it
    # is would override it) but by the queue once the stop is behind the drone.
    sent = [i["payload"] for i in outbox.items() if i["topic"].startswith("ACME_A/")]
    assert not [m for m in sent if m.get("command") == "navigate"]
    assert not [m for m in sent if m.get("then") == "return"]
    assert slot.hold_sent_at is None
    Drone.objects.filter(pk=failing.pk).update(mission=None)  # its heartbeat: no mission
    with django_capture_on_commit_callbacks(execute=True):
        landing.keep_to_hold(LandingSlot.objects.get(pk=slot.pk))
    sent = [i["payload"] for i in outbox.items() if i["topic"].startswith("ACME_A/")]
    holds = [m for m in sent if m.get("command") == "navigate"]
    assert len(holds) == 1 and holds[0]["params"]["altitude_delta"] == pytest.approx(14.0)
    queued = Reservation.objects.get(drone=failing, ended_at__isnull=True)
    flying_in = Reservation.objects.get(assignment=replacing, ended_at__isnull=True)
    assert _clear_of(flying_in, queued)

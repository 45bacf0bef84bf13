"""The conflict rule on corridors, without the database: crossing legs at one height and
time conflict, 20 m apart in height or minutes apart in time they do not, and the index
answers as the plain pairwise definition on random airspaces."""

from __future__ import annotations

import random

from airspace.corridors import Leg, Pace, flight_legs, offset
from airspace.index import Airspace, Flight, Reserved, first_conflict_pairwise

ORIGIN = (40.6303, -8.6575)
T = 1_800_000_000.0


def leg(north0, east0, north1, east1, height, t0=T, t1=T + 120.0):  # type: ignore[no-untyped-def]
    a = offset(*ORIGIN, north0, east0)
    b = offset(*ORIGIN, north1, east1)
    return Leg(*a, *b, height - 2.0, height + 2.0, t0, t1)


def reserved(legs: list[Leg], drone_id: str = "ACME_A", horizontal: float = 30.0) -> Reserved:
    return Reserved("1", drone_id, 1, [x.to_list() for x in legs], 2.0, horizontal, 10.0)


def flight(legs: list[Leg]) -> Flight:
    return Flight(legs, 2.0, 30.0, 10.0)


def test_legs_crossing_at_one_height_and_time_conflict_at_the_crossing():
    other = reserved([leg(-100, 0, 100, 0, 20.0)])
    mine = flight([leg(0, -100, 0, 100, 20.0, T + 30, T + 200)])
    clash = Airspace([other]).first_conflict(mine)
    assert clash is not None and clash.reserved.drone_id == "ACME_A"
    assert abs(clash.lat - ORIGIN[0]) < 1e-6 and abs(clash.lon - ORIGIN[1]) < 1e-6
    assert clash.at == T + 30 and clash.distance_m < 0


def test_twenty_metres_apart_in_height_they_do_not():
    other = reserved([leg(-100, 0, 100, 0, 20.0)])
    assert Airspace([other]).first_conflict(flight([leg(0, -100, 0, 100, 40.0)])) is None
    # 10 m apart the bands (±2 m) are 6 m apart: closer than the vertical minimum.
    assert Airspace([other]).first_conflict(flight([leg(0, -100, 0, 100, 30.0)])) is not None


def test_disjoint_windows_or_enough_distance_do_not_conflict():
    other = reserved([leg(-100, 0, 100, 0, 20.0)])
    later = leg(0, -100, 0, 100, 20.0, T + 121.0, T + 300.0)
    assert Airspace([other]).first_conflict(flight([later])) is None
    # Parallel 35 m away: 31 m between the corridors' edges, beyond 30 m.
    assert Airspace([other]).first_conflict(flight([leg(-100, 35, 100, 35, 20.0)])) is None
    # 33 m away: 29 m between the edges.
    assert Airspace([other]).first_conflict(flight([leg(-100, 33, 100, 33, 20.0)])) is not None


def test_a_pair_keeps_the_larger_of_its_two_minima():
    other = reserved([leg(-100, 0, 100, 0, 20.0)], horizontal=60.0)
    assert Airspace([other]).first_conflict(flight([leg(-100, 50, 100, 50, 20.0)])) is not None


def _random_reservation(rng: random.Random, key: int) -> Reserved:
    north, east = rng.uniform(-600, 600), rng.uniform(-600, 600)
    height, t = rng.choice([10.0, 20.0, 30.0, 40.0]), T + rng.uniform(0, 600)
    legs = []
    for _ in range(rng.randint(1, 8)):
        n2, e2 = north + rng.uniform(-200, 200), east + rng.uniform(-200, 200)
        legs.append(leg(north, east, n2, e2, height, t, t + rng.uniform(20, 200)))
        north, east, t = n2, e2, t + rng.uniform(10, 100)
    return Reserved(str(key), f"D{key}", 1, [x.to_list() for x in legs], 2.0, 30.0, 10.0)


def test_the_index_answers_as_every_pair_would():
    rng = random.Random(11)
    found = 0
    for _ in range(150):
        others = [_random_reservation(rng, k) for k in range(rng.randint(1, 40))]
        mine = flight([Leg.from_list(v) for v in _random_reservation(rng, 999).legs])
        indexed = Airspace(others).first_conflict(mine)
        plain = first_conflict_pairwise(others, mine)
        assert (indexed is None) == (plain is None)
        if indexed is not None:
            found += 1
            assert (indexed.leg, indexed.reserved.key, indexed.at) == (
                plain.leg,
                plain.reserved.key,
                plain.at,
            )
            assert abs(indexed.lat - plain.lat) < 1e-9 and abs(indexed.lon - plain.lon) < 1e-9
    assert 20 < found < 150  # both answers occur


def test_a_flights_legs_are_timed_at_its_speeds_and_widened():
    pace = Pace(speed_m_s=5.0, climb_m_s=2.0, slack=0.5, early=0.5, buffer_s=30.0, hold_s=60.0)
    target = offset(*ORIGIN, 100.0, 0.0)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 20.0}},
        # Climbed before it leaves (without the wait it leaves on a slant: test_slant.py).
        {"command": "wait_for_flight"},
        {"command": "navigate", "params": {"lat": target[0], "lon": target[1]}},
        {"command": "land"},
    ]
    legs, airborne_by = flight_legs(steps, (*ORIGIN, 0.0), T, pace)
    climb, cruise, descent = legs
    # 10 s to climb 20 m, 20 s to fly 100 m, 10 s down; windows ±30 s, starts × 0.5,
    # ends × 1.5.
    assert (climb.t0, climb.t1) == (T - 30, T + 10 * 1.5 + 30)
    assert (cruise.t0, cruise.t1) == (T + 10 * 0.5 - 30, T + 30 * 1.5 + 30)
    assert (cruise.low, cruise.high) == (18.0, 22.0) and (descent.low, descent.high) == (0.0, 22.0)
    assert abs(cruise.lat1 - target[0]) < 1e-12 and airborne_by == T + 30
    # Not landing: it hovers at its last waypoint for hold_s.
    hovering, _ = flight_legs(steps[:4], (*ORIGIN, 0.0), T, pace)
    assert hovering[-1].lat0 == hovering[-1].lat1 and hovering[-1].t1 == T + 90 * 1.5 + 30

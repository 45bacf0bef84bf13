"""Separation check speed: a 200-waypoint mission against 1 000 active reservations.

Run: .venv/bin/python -m bench.bench_airspace

The indexed check (airspace/index.py `Airspace`: built from the reservations, then asked
for the first conflict, both timed) against the plain definition, every pair of legs in
pure Python (`first_conflict_pairwise`), on the same airspace in the same run; both must
give the same answer. The reservations are missions of 5 to 40 waypoints flown at 10 to
60 m from homes spread over a 4 × 4 km site, all in the air at once; the mission is a lawnmower survey of
200 waypoints over 1 × 0.6 km in the middle of it, at a height of its own (no conflict,
so every pair must be ruled out), and again at a height the others use (a conflict).
"""

from __future__ import annotations

import random

from airspace.corridors import Pace, flight_legs, offset
from airspace.index import Airspace, Flight, Reserved, first_conflict_pairwise
from bench.common import best_of, record

ORIGIN = (40.6303, -8.6575)
NOW = 1_800_000_000.0
PACE = Pace()
RESERVATIONS = 1000
SURVEY_WAYPOINTS = 200
GOAL_MS = 50.0


def _mission(
    lat: float, lon: float, height: float, waypoints: int, rng: random.Random
) -> list[dict]:
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": height}}]
    for _ in range(waypoints):
        lat, lon = offset(lat, lon, rng.uniform(-150, 150), rng.uniform(-150, 150))
        steps.append({"command": "navigate", "params": {"lat": lat, "lon": lon}})
    return [*steps, {"command": "land"}]


def reservations(rng: random.Random) -> list[Reserved]:
    out = []
    for k in range(RESERVATIONS):
        height = rng.choice([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
        home = offset(*ORIGIN, rng.uniform(-2000, 2000), rng.uniform(-2000, 2000))
        steps = _mission(*home, height, rng.randint(5, 40), rng)
        legs, _ = flight_legs(steps, (*home, 0.0), NOW + rng.uniform(0, 600), PACE)
        out.append(Reserved(str(k), f"D{k}", 1, [leg.to_list() for leg in legs], 2.0, 30.0, 10.0))
    return out


def survey(height: float) -> Flight:
    """A lawnmower of SURVEY_WAYPOINTS waypoints, 20 rows 30 m apart, 10 per row."""
    steps = [{"command": "takeoff", "params": {"altitude": height}}]
    for row in range(SURVEY_WAYPOINTS // 10):
        columns = range(10) if row % 2 == 0 else range(9, -1, -1)
        for col in columns:
            lat, lon = offset(*ORIGIN, -300 + row * 30.0, -500 + col * 100.0)
            steps.append({"command": "navigate", "params": {"lat": lat, "lon": lon}})
    legs, _ = flight_legs(steps, (*ORIGIN, 0.0), NOW + 60, PACE)
    return Flight(legs, 2.0, 30.0, 10.0)


def _same(a: object, b: object) -> bool:
    if a is None or b is None:
        return a is b
    return (a.leg, a.reserved.key, round(a.at, 6)) == (b.leg, b.reserved.key, round(b.at, 6))  # type: ignore[attr-defined]


def measure(reserved: list[Reserved], flight: Flight, label: str) -> None:
    indexed = Airspace(reserved).first_conflict(flight)
    plain = first_conflict_pairwise(reserved, flight)
    assert _same(indexed, plain), (indexed, plain)
    fast = best_of(lambda: Airspace(reserved).first_conflict(flight), repeat=7) * 1000
    slow = best_of(lambda: first_conflict_pairwise(reserved, flight), repeat=1) * 1000
    legs = sum(len(r.legs) for r in reserved)
    record(
        f"airspace.conflict_check_{label}_ms",
        value=round(fast, 3),
        unit="ms",
        baseline_name="every pair of legs in pure Python",
        baseline_value=round(slow, 3),
        higher_is_better=False,
        goal=f"<= {GOAL_MS:g} ms for a {SURVEY_WAYPOINTS}-waypoint mission against "
        f"{RESERVATIONS} reservations",
        reserved_legs=legs,
        mission_legs=len(flight.legs),
        conflict=indexed is not None,
    )


def main() -> None:
    rng = random.Random(7)
    reserved = reservations(rng)
    measure(reserved, survey(75.0), "clear")
    measure(reserved, survey(30.0), "conflicting")


if __name__ == "__main__":
    main()

"""Laying a split's part clear of a crowded airspace: layers, then a staggered departure.

Run: .venv/bin/python -m bench.bench_stagger

The platform's own plans (a collaboration's split, a replacement) are laid by
airspace/stagger.py `lay`: the reserved legs near the part's ground track are picked once,
and the wait on the ground jumps to the first one that may clear each conflict met. The
baseline is the plain definition, `lay_plainly`: every layer, then every multiple of the
10 s step up to 600 s on every layer, each against the whole airspace; both must give the
same answer, in the same run. The airspace is bench_airspace's: 1 000 missions of 5 to 40
waypoints at 10 to 60 m from homes over a 4 × 4 km site, all flying within the next ten
minutes. The part takes off in the middle of the site and flies a 20-waypoint row; it is
laid twice: with the envelope's ceiling at 30 m (two layers: only a wait clears it) and
at 120 m (eight layers).
"""

from __future__ import annotations

import random

from airspace.corridors import offset
from airspace.index import Airspace
from airspace.stagger import Search, lay, lay_plainly
from bench.bench_airspace import NOW, ORIGIN, PACE, _same, reservations
from bench.common import best_of, record

GOAL_MS = 500.0
LAYER_M = 14.0  # 10 m vertical minimum + 2 × 2 m tolerance


def part() -> list[dict]:
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10.0}}]
    lat, lon = ORIGIN
    for _ in range(20):
        lat, lon = offset(lat, lon, 0.0, 40.0)
        steps += [
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "wait_for_flight"},
        ]
    return [*steps, {"command": "land"}]


def measure(airspace: Airspace, ceiling: float) -> None:
    steps = part()
    layers = [10.0 + LAYER_M * k for k in range(int((ceiling - 10.0) // LAYER_M) + 1)]
    search = Search((*ORIGIN, 0.0), NOW, PACE, (30.0, 10.0), 10.0, 600.0)
    fast, clash = lay(steps, layers, airspace, search)
    plain, plain_clash = lay_plainly(steps, layers, airspace, search)
    if fast is None or plain is None:
        same = fast is plain and _same(clash, plain_clash)
    else:
        same = (fast.delay_s, fast.steps) == (plain.delay_s, plain.steps)
    assert same, (fast, plain)
    quick = best_of(lambda: lay(steps, layers, airspace, search), repeat=5) * 1000
    slow = best_of(lambda: lay_plainly(steps, layers, airspace, search), repeat=1) * 1000
    record(
        f"airspace.lay_part_ceiling_{ceiling:g}m_ms",
        value=round(quick, 3),
        unit="ms",
        baseline_name="every layer and every 10 s wait against the whole airspace",
        baseline_value=round(slow, 3),
        higher_is_better=False,
        goal=f"<= {GOAL_MS:g} ms to lay a 20-waypoint part against 1000 reservations",
        layers=len(layers),
        outcome="declined"
        if fast is None
        else f"wait {fast.delay_s:g} s, "
        f"takeoff to {next(s['params']['altitude'] for s in fast.steps if s['command'] == 'takeoff'):g} m",
    )


def main() -> None:
    airspace = Airspace(reservations(random.Random(7)))
    measure(airspace, 30.0)
    measure(airspace, 120.0)


if __name__ == "__main__":
    main()

"""Remote ID costs: the airworthiness verdict drone selection adds, and checking an EU
operator registration number.

Run: .venv/bin/python -m bench.bench_remote_id

1. The verdict (fleet/airworthiness.py) for 1 000 drones of an organisation that requires
   Remote ID, half of them reporting a failing module, against building their selection
   candidates alone (missions/selection.py `Candidate`, what every selection did before),
   on the same in-memory rows: what the verdict adds to a selection per drone.
2. `parse_operator_id` on EN 4709-002 numbers (shape, state, Luhn mod 36 checksum) against
   matching the shape alone with its regular expression.
"""

from __future__ import annotations

import os
import random

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
django.setup()

from bench.common import best_of, record  # noqa: E402
from fleet import airworthiness  # noqa: E402
from fleet.identity import EU_OPERATOR_RE, luhn_mod36, parse_operator_id  # noqa: E402
from fleet.models import Drone, Organisation  # noqa: E402
from missions.selection import Candidate  # noqa: E402

DRONES = 1000
NUMBERS = 1000
ALPHABET = "0123456789abcdefghijklmnopqrstuvwxyz"


def fleet(rng: random.Random) -> list[Drone]:
    organisation = Organisation(name="Bench", slug="bench", require_remote_id=True)
    organisation.operator_id = "FIN87astrdge12k8"
    drones = []
    for k in range(DRONES):
        failing = k % 2 == 0
        drones.append(
            Drone(
                organisation=organisation,
                drone_id=f"BENCH_{k:04d}",
                online=True,
                lat=40.63 + rng.uniform(-0.01, 0.01),
                lon=-8.65 + rng.uniform(-0.01, 0.01),
                battery_remaining=rng.uniform(0.2, 1.0),
                serial_number=f"MFR1C{k:012d}",
                fc={"protocol": "mavlink", "remote_id": {"ok": not failing, "error": "x"}},
            )
        )
    return drones


def candidates(drones: list[Drone], *, verdict: bool) -> list[Candidate]:
    return [
        Candidate(
            drone_id=d.drone_id,
            online=d.online,
            in_mission=False,
            battery=d.battery_remaining,
            position=(d.lat, d.lon),
            airworthy=airworthiness.verdict(d).airworthy if verdict else True,
        )
        for d in drones
    ]


def numbers(rng: random.Random) -> list[str]:
    out = []
    for _ in range(NUMBERS):
        base = "".join(rng.choice(ALPHABET) for _ in range(12))
        secret = "".join(rng.choice(ALPHABET) for _ in range(3))
        out.append(f"DEU{base}{luhn_mod36(base + secret)}-{secret}")
    return out


def main() -> None:
    rng = random.Random(7)
    drones = fleet(rng)
    assert sum(not c.airworthy for c in candidates(drones, verdict=True)) == DRONES // 2
    with_verdict = best_of(lambda: candidates(drones, verdict=True))
    without = best_of(lambda: candidates(drones, verdict=False))
    record(
        "remote_id.selection_candidates_1000_drones_ms",
        value=with_verdict * 1000,
        unit="ms",
        baseline_name="the same candidates without the verdict",
        baseline_value=without * 1000,
        higher_is_better=False,
        goal="under 10 ms for 1 000 drones",
    )
    given = numbers(rng)
    assert all(len(parse_operator_id(n)) == 16 for n in given)
    parse = best_of(lambda: [parse_operator_id(n) for n in given])
    shape = best_of(lambda: [EU_OPERATOR_RE.match(n) for n in given])
    record(
        "remote_id.operator_number_check_us",
        value=parse / NUMBERS * 1e6,
        unit="µs",
        baseline_name="its regular expression alone",
        baseline_value=shape / NUMBERS * 1e6,
        higher_is_better=False,
        goal="under 50 µs a number",
    )


if __name__ == "__main__":
    main()

"""Checklist costs: the automatic items drone selection measures for the platform's own
work.

Run: .venv/bin/python -m bench.bench_checklists

The automatic items that need no telemetry query (battery, link, envelope, Remote ID;
checklists/checks.py) measured for 1 000 drones of an organisation that requires
checklists, a third of them failing one, against building their selection candidates
alone (missions/selection.py `Candidate`), on the same in-memory rows: what the items add
to a selection per drone. A `gps` item adds one indexed telemetry probe per drone, and
`airworthy` the verdict measured by bench_remote_id, neither of them here.
"""

from __future__ import annotations

import os
import random
from datetime import timedelta

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
django.setup()

from django.utils import timezone  # noqa: E402

from bench.common import best_of, record  # noqa: E402
from checklists import gate  # noqa: E402
from checklists.items import clean_items  # noqa: E402
from fleet.models import Drone, Organisation  # noqa: E402
from missions.selection import Candidate  # noqa: E402

DRONES = 1000
ITEMS = clean_items(
    [
        {"kind": "auto", "check": "battery", "threshold": 0.5},
        {"kind": "auto", "check": "link", "threshold": 15},
        {"kind": "auto", "check": "envelope"},
        {"kind": "auto", "check": "remote_id"},
    ]
)


def fleet(rng: random.Random) -> list[Drone]:
    organisation = Organisation(name="Bench", slug="bench", require_remote_id=False)
    seen = timezone.now() - timedelta(seconds=2)
    return [
        Drone(
            organisation=organisation,
            drone_id=f"BENCH_{k:04d}",
            online=True,
            last_seen=seen,
            lat=40.63 + rng.uniform(-0.01, 0.01),
            lon=-8.65 + rng.uniform(-0.01, 0.01),
            battery_remaining=0.3 if k % 3 == 0 else rng.uniform(0.6, 1.0),
            fc={"protocol": "mavlink", "connected": True},
        )
        for k in range(DRONES)
    ]


def candidates(drones: list[Drone], items: list[dict]) -> list[Candidate]:
    shared: dict = {}
    return [
        Candidate(
            drone_id=d.drone_id,
            online=d.online,
            in_mission=False,
            battery=d.battery_remaining,
            position=(d.lat, d.lon),
            checks_pass=not gate.failing(d, items, shared),
        )
        for d in drones
    ]


def main() -> None:
    drones = fleet(random.Random(7))
    failing = sum(not c.checks_pass for c in candidates(drones, ITEMS))
    assert failing == len(range(0, DRONES, 3)), failing
    with_items = best_of(lambda: candidates(drones, ITEMS), repeat=20)
    without = best_of(lambda: candidates(drones, []), repeat=20)
    record(
        "checklists.selection_automatic_items_1000_drones_ms",
        value=with_items * 1000,
        unit="ms",
        baseline_name="the same candidates without automatic items",
        baseline_value=without * 1000,
        higher_is_better=False,
        goal="under 50 ms for 1 000 drones",
    )


if __name__ == "__main__":
    main()

"""The fleet's trend of a log check over 1 000 flights: the API's computation and the page.

Run: .venv/bin/python -m bench.bench_log_trends

A database of its own holds one organisation with DRONES drones and FLIGHTS checked logs
spread over them, each with its ten checks' figures (what the import keeps from each
health report, logs/trends.py). The first figure is `fleet_trend` for the vibration
check: every drone's figures in flight order and its newest judged against its own
history and the fleet. The second is the whole trend page (GET /logs/trends/, rendered by
Django for a signed-in member). The baseline, measured in the same run, is the naive way
to gather the same figures: one query per log for its figure.
"""

from __future__ import annotations

import os
from datetime import UTC, datetime, timedelta

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_log_trends_{os.getpid()}"

from bench.common import best_of, record  # noqa: E402

DRONES = 20
FLIGHTS = 1000
CHECK = "vibration"
GOAL = "the fleet trend of 1 000 flights in under 1 s"


def fleet(organisation) -> None:  # type: ignore[no-untyped-def]
    """FLIGHTS ready logs over DRONES drones, one a day each, every check's figure kept."""
    import numpy as np

    from fleet.models import Drone
    from logs.checks import CHECKS
    from logs.models import FlightLog, LogFigure, LogStatus

    rng = np.random.default_rng(3)
    drones = [
        Drone.objects.create(organisation=organisation, drone_id=f"BENCH_{i:02d}")
        for i in range(DRONES)
    ]
    day0 = datetime(2026, 1, 1, tzinfo=UTC)
    logs = FlightLog.objects.bulk_create(
        FlightLog(
            organisation=organisation,
            name=f"flight-{i}.ulg",
            status=LogStatus.READY,
            drone=drones[i % DRONES],
            flown_at=day0 + timedelta(days=i // DRONES),
        )
        for i in range(FLIGHTS)
    )
    LogFigure.objects.bulk_create(
        LogFigure(log=log, name=name, status="pass", value=float(rng.normal(2.0, 0.1)), unit="")
        for log in logs
        for name in CHECKS
    )


def naive(organisation) -> int:  # type: ignore[no-untyped-def]
    """The same figures gathered one query per log, in flight order per drone."""
    from logs.models import FlightLog, LogFigure

    found: dict[int, list[float]] = {}
    for log in FlightLog.objects.filter(organisation=organisation, drone__isnull=False).order_by(
        "drone_id", "flown_at"
    ):
        figure = LogFigure.objects.get(log=log, name=CHECK)
        found.setdefault(log.drone_id, []).append(figure.value)
    return sum(len(v) for v in found.values())


def main() -> None:
    import django

    django.setup()
    from django.contrib.auth import get_user_model
    from django.db import connection
    from django.test import Client

    from fleet.models import Membership, Organisation, Role
    from logs.trends import fleet_trend

    original_database = connection.settings_dict["NAME"]
    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    try:
        organisation = Organisation.objects.create(slug="bench", name="Bench")
        fleet(organisation)
        user = get_user_model().objects.create_user("bench", password="x")
        Membership.objects.create(user=user, organisation=organisation, role=Role.VIEWER)
        client = Client()
        client.force_login(user)

        flights = sum(len(d["points"]) for d in fleet_trend(organisation, CHECK))
        assert flights == FLIGHTS == naive(organisation), flights
        baseline = best_of(lambda: naive(organisation), repeat=3)
        trend = best_of(lambda: fleet_trend(organisation, CHECK), repeat=5)
        page = best_of(lambda: client.get(f"/logs/trends/?check={CHECK}"), repeat=5)
        assert client.get("/logs/trends/").status_code == 200
        common = {
            "unit": "s",
            "baseline_name": "one query per log for its figure",
            "baseline_value": baseline,
            "higher_is_better": False,
            "goal": GOAL,
            "flights": FLIGHTS,
            "drones": DRONES,
        }
        record("logs.trend_1000_flights", value=trend, **common)
        record("logs.trend_page_1000_flights", value=page, **common)
    finally:
        if connection.settings_dict["NAME"] != original_database:
            connection.creation.destroy_test_db(original_database, verbosity=0)


if __name__ == "__main__":
    main()

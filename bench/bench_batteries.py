"""Battery bookkeeping costs: a pack's figures after a flight, and the sag estimate.

Run: .venv/bin/python -m bench.bench_batteries

1. `batteries.usage.refresh` for a pack with 1 000 recorded flights (a database of its
   own): its totals, capacity, resistance, health and retirement, computed again as each
   flight's record is written. The baseline, in the same run, is only reading the pack's
   1 000 flight rows, the floor of any recomputation from them.
2. The internal-resistance estimate (`batteries.health.SagEstimator`) over an hour of
   battery samples at 10 Hz with a current step every 10 s, against walking the same
   samples (what the flight record's one pass already does).
"""

from __future__ import annotations

import os
from datetime import UTC, datetime, timedelta

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_batteries_{os.getpid()}"

from bench.common import best_of, record  # noqa: E402

FLIGHTS = 1000
HOUR_SAMPLES = 36_000  # 10 Hz for an hour


def pack_with_flights():  # type: ignore[no-untyped-def]
    """One organisation, drone and pack with FLIGHTS recorded flights counted against it."""
    from batteries.models import Battery, BatteryFlight
    from fleet.models import Drone, Organisation
    from records.models import FlightRecord

    organisation = Organisation.objects.create(slug="bench", name="Bench")
    drone = Drone.objects.create(organisation=organisation, drone_id="BENCH_1")
    battery = Battery.objects.create(
        organisation=organisation, serial="PACK-1", drone=drone, rated_energy_wh=80.0
    )
    start = datetime(2026, 1, 1, tzinfo=UTC)
    records = FlightRecord.objects.bulk_create(
        FlightRecord(
            organisation=organisation, drone=drone, drone_ident=drone.drone_id,
            origin="command", started_at=start + timedelta(hours=k),
            ended_at=start + timedelta(hours=k, minutes=20), duration_s=1200.0,
            battery_start=1.0, battery_end=0.3, energy_wh=55.0, battery=battery.serial,
        )
        for k in range(FLIGHTS)
    )  # fmt: skip
    BatteryFlight.objects.bulk_create(
        BatteryFlight(
            battery=battery, record=r, started_at=r.started_at, soc_drop=0.7, cycles=0.7,
            energy_wh=55.0, capacity_wh=55.0 / 0.7, resistance_ohm=0.02,
        )
        for r in records
    )  # fmt: skip
    return battery


def read_rows(battery) -> list:  # type: ignore[no-untyped-def]
    return list(battery.uses.values_list("cycles", "energy_wh", "capacity_wh", "resistance_ohm"))


def battery_samples() -> list[tuple[float, float, float]]:
    out = []
    for i in range(HOUR_SAMPLES):
        t = i / 10.0
        current = 25.0 if int(t / 10.0) % 2 else 12.0
        out.append((t, 16.4 - t / 1200.0 - 0.02 * current, current))
    return out


def sag(samples: list[tuple[float, float, float]]) -> float | None:
    from batteries.health import SagEstimator

    estimator = SagEstimator()
    for ts, volts, amps in samples:
        estimator.add(ts, volts, amps)
    return estimator.result()


def walk(samples: list[tuple[float, float, float]]) -> float:
    total = 0.0
    for _ts, volts, amps in samples:
        total += volts * amps
    return total


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    from batteries import usage

    original = connection.settings_dict["NAME"]
    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    try:
        battery = pack_with_flights()
        assert usage.refresh(battery).flights == FLIGHTS
        baseline = best_of(lambda: read_rows(battery), repeat=5)
        refresh = best_of(lambda: usage.refresh(battery), repeat=5)
    finally:
        connection.creation.destroy_test_db(original, verbosity=0)
    record(
        "batteries.refresh_1000_flights_ms",
        value=refresh * 1000,
        unit="ms",
        baseline_name="reading the pack's 1 000 flight rows",
        baseline_value=baseline * 1000,
        higher_is_better=False,
        goal="a pack with 1 000 flights brought up to date in under 50 ms",
        flights=FLIGHTS,
    )
    samples = battery_samples()
    assert abs(sag(samples) - 0.02) < 1e-3
    record(
        "batteries.sag_one_hour_ms",
        value=best_of(lambda: sag(samples), repeat=3) * 1000,
        unit="ms",
        baseline_name="walking the same samples",
        baseline_value=best_of(lambda: walk(samples), repeat=3) * 1000,
        higher_is_better=False,
        goal="an hour of 10 Hz battery samples in under 100 ms",
        samples=HOUR_SAMPLES,
    )


if __name__ == "__main__":
    main()

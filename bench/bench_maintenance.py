"""What maintenance adds to the airworthiness verdict, which drone selection asks for every
drone of the organisation (replacement, collaboration, panic, mission start).

Run: .venv/bin/python -m bench.bench_maintenance

A fleet of DRONES drones (a database of its own), each with FLIGHTS recorded flights, a
schedule of its own and two schedules of its gear model, one sign-off each and an open
bulletin for half of them. Two figures, each with its baseline from the same run:

- `maintenance.verdict_200_drones_ms`: the verdict drone by drone for the whole fleet with
  the maintenance reason; baseline, the same without that reason.
- `maintenance.verdicts_batch_200_drones_ms`: the verdicts of the whole fleet at once
  (`airworthiness.verdicts`, what drone selection asks), every reason; baseline, the
  verdict drone by drone with every reason.
"""

from __future__ import annotations

import os
from datetime import UTC, datetime, timedelta

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_maintenance_{os.getpid()}"

from bench.common import best_of, record  # noqa: E402

DRONES = 200
FLIGHTS = 50


def fleet():  # type: ignore[no-untyped-def]
    """The organisation's drones, with their flights, schedules, sign-offs and bulletins."""
    from fleet.models import Drone, Organisation
    from maintenance.models import Bulletin, LogEntry, Schedule
    from records.models import FlightRecord

    organisation = Organisation.objects.create(slug="bench", name="Bench")
    start = datetime(2026, 1, 1, tzinfo=UTC)
    drones = Drone.objects.bulk_create(
        Drone(organisation=organisation, drone_id=f"BENCH_{k:04d}",
              specs={"MODEL": "X8" if k % 2 else "H6"}, created_at=start)
        for k in range(DRONES)
    )  # fmt: skip
    Drone.objects.filter(organisation=organisation).update(created_at=start)
    FlightRecord.objects.bulk_create(
        FlightRecord(
            organisation=organisation, drone=d, drone_ident=d.drone_id, origin="command",
            started_at=start + timedelta(hours=k), ended_at=start + timedelta(hours=k, minutes=20),
            duration_s=1200.0,
        )
        for d in drones
        for k in range(FLIGHTS)
    )  # fmt: skip
    Schedule.objects.create(organisation=organisation, model="X8", name="Motors", every_hours=100)
    Schedule.objects.create(organisation=organisation, model="H6", name="Yearly", every_days=365)
    Bulletin.objects.create(organisation=organisation, model="X8", title="Arms", text="Check.")
    for drone in drones:
        own = Schedule.objects.create(
            organisation=organisation, drone=drone, name="Props", every_flights=200
        )
        LogEntry.objects.create(
            organisation=organisation, drone=drone, drone_ident=drone.drone_id, schedule=own,
            item_name=own.name, signed_by_name="bench", notes="props",
            signed_at=start + timedelta(hours=FLIGHTS // 2),
        )  # fmt: skip
    return list(Drone.objects.filter(organisation=organisation).select_related("organisation"))


def verdicts(drones, reasons) -> int:  # type: ignore[no-untyped-def]
    from fleet import airworthiness

    saved = list(airworthiness.REASONS)
    airworthiness.REASONS[:] = reasons
    try:
        return sum(airworthiness.verdict(d).airworthy for d in drones)
    finally:
        airworthiness.REASONS[:] = saved


def batch(drones) -> int:  # type: ignore[no-untyped-def]
    from fleet import airworthiness

    return sum(v.airworthy for v in airworthiness.verdicts(drones).values())


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    from fleet import airworthiness

    original = connection.settings_dict["NAME"]
    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    try:
        drones = fleet()
        every = list(airworthiness.REASONS)
        others = [r for r in every if r is not airworthiness.maintenance_due]
        assert verdicts(drones, every) == DRONES // 2  # the X8s have the bulletin open
        assert airworthiness.verdicts(drones) == {d.pk: airworthiness.verdict(d) for d in drones}
        baseline = best_of(lambda: verdicts(drones, others), repeat=3)
        figure = best_of(lambda: verdicts(drones, every), repeat=3)
        together = best_of(lambda: batch(drones), repeat=5)
    finally:
        connection.creation.destroy_test_db(original, verbosity=0)
    record(
        "maintenance.verdict_200_drones_ms",
        value=figure * 1000,
        unit="ms",
        baseline_name="the verdict without the maintenance reason",
        baseline_value=baseline * 1000,
        higher_is_better=False,
        goal="maintenance adds under 2 ms a drone to a selection's verdicts",
        drones=DRONES,
        flights_per_drone=FLIGHTS,
    )
    record(
        "maintenance.verdicts_batch_200_drones_ms",
        value=together * 1000,
        unit="ms",
        baseline_name="the verdict drone by drone, every reason",
        baseline_value=figure * 1000,
        higher_is_better=False,
        goal="a selection judges 200 candidates, maintenance included, in under 100 ms",
        drones=DRONES,
        flights_per_drone=FLIGHTS,
    )


if __name__ == "__main__":
    main()

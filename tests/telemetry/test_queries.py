"""Latest values, downsampled ranges checked against numpy, partitions and retention."""

from __future__ import annotations

from datetime import UTC, date, datetime, timedelta

import numpy as np
import psycopg
import pytest

from telemetry import queries, storage
from telemetry.storage import Sample


@pytest.fixture
def conn(world_tx):
    with psycopg.connect(queries.conninfo_from_settings(), autocommit=True) as connection:
        yield connection


def _samples(drone_pk: int, start: datetime, seconds: int, hz: int, seed: int = 1):
    """Irregular 10 Hz-ish samples with a numeric, an often-missing and an enum field."""
    rng = np.random.default_rng(seed)
    n = seconds * hz
    base = int(start.timestamp() * 1_000_000)
    # Whole microseconds, as PostgreSQL stores them, so numpy sees the very same instants.
    us = base + np.sort(rng.choice(seconds * 1_000_000, size=n, replace=False))
    pressure = rng.normal(100.0, 2.0, n)
    temperature = rng.normal(20.0, 5.0, n)
    samples = []
    for i in range(n):
        fields = {"Pressure": float(pressure[i]), "Mode": "Fix3D"}
        if i % 3:
            fields["Temperature"] = float(temperature[i])
        samples.append(Sample(int(us[i]) / 1e6, drone_pk, "BaroAltitude", fields))
    return us, pressure, temperature, samples


def _numpy_buckets(us, values, mask, start: datetime, width: timedelta):
    start_us = int(start.timestamp() * 1_000_000)
    width_us = int(width / timedelta(microseconds=1))
    index = (us[mask] - start_us) // width_us
    out = {}
    for b in np.unique(index):
        chosen = values[mask][index == b]
        t = (start_us + int(b) * width_us) / 1e6
        out[t] = (chosen.min(), chosen.max(), chosen.mean(), len(chosen))
    return out


def test_a_range_is_cut_into_buckets_whose_min_max_and_avg_match_numpy(world_tx, conn):
    start = datetime(2026, 3, 1, 12, 0, tzinfo=UTC)
    us, pressure, temperature, samples = _samples(world_tx.drone.pk, start, 600, 10)
    storage.copy_samples(conn, samples)
    q_start, q_end = start + timedelta(seconds=17.3), start + timedelta(seconds=512.9)

    result = queries.query_range(
        world_tx.drone.pk,
        "BaroAltitude",
        ["Pressure", "Temperature", "Mode"],
        q_start,
        q_end,
        points=97,
        source="raw",
    )

    assert result.bucket == queries.bucket_width(q_start, q_end, 97)
    assert len(result.t) <= 97
    in_range = (us >= int(q_start.timestamp() * 1e6)) & (us < int(q_end.timestamp() * 1e6))
    has_temperature = np.arange(len(us)) % 3 != 0
    for name, values, mask in (
        ("Pressure", pressure, in_range),
        ("Temperature", temperature, in_range & has_temperature),
    ):
        expected = _numpy_buckets(us, values, mask, q_start, result.bucket)
        assert [round(t, 6) for t in result.t] == [round(t, 6) for t in expected]
        series = result.series[name]
        for i, (lo, hi, avg, _) in enumerate(expected.values()):
            assert series.min[i] == pytest.approx(lo)
            assert series.max[i] == pytest.approx(hi)
            assert series.avg[i] == pytest.approx(avg)
    counts = _numpy_buckets(us, pressure, in_range, q_start, result.bucket)
    assert result.count == [c[3] for c in counts.values()]
    # An enum is not a number: it is in no aggregate rather than breaking the query.
    assert set(result.series["Mode"].avg) == {None}


def test_latest_gives_each_objects_newest_sample(world_tx, conn):
    t = datetime(2026, 3, 2, tzinfo=UTC).timestamp()
    pk = world_tx.drone.pk
    storage.copy_samples(
        conn,
        [
            Sample(t, pk, "Gyros", {"x": 1.0}),
            Sample(t + 2, pk, "Gyros", {"x": 2.0}),
            Sample(t + 1, pk, "Gyros", {"x": 3.0}),
            Sample(t, pk, "FlightBatteryState", {"Voltage": 16.1}),
            Sample(t + 5, world_tx.other_drone.pk, "Gyros", {"x": 9.0}),
        ],
    )
    latest = queries.latest(pk)
    assert latest == {
        "Gyros": {"ts": t + 2, "fields": {"x": 2.0}},
        "FlightBatteryState": {"ts": t, "fields": {"Voltage": 16.1}},
    }
    assert queries.latest(pk, ["FlightBatteryState"]) == {
        "FlightBatteryState": {"ts": t, "fields": {"Voltage": 16.1}}
    }
    many = queries.latest_for_drones([pk, world_tx.other_drone.pk], ["Gyros"])
    assert many[world_tx.other_drone.pk]["Gyros"]["fields"] == {"x": 9.0}


def _partition_days(conn, table):
    return {day for _, day in storage.partitions(conn, table)}


def test_maintenance_creates_partitions_ahead_rolls_up_and_drops_old_days(world_tx, conn):
    pk = world_tx.drone.pk
    today = date(2031, 6, 10)
    old_day = date(2031, 6, 5)
    start = datetime.combine(old_day, datetime.min.time(), UTC)
    us, pressure, _, samples = _samples(pk, start, 180, 10, seed=7)
    try:
        # No partition covers that day yet: the rows land in the default partition.
        storage.copy_samples(conn, samples)
        assert conn.execute(
            "SELECT count(*) FROM telemetry_sample_default WHERE drone_id = %s", (pk,)
        ).fetchone()[0] == len(samples)
        assert storage.ensure_partition(conn, storage.SAMPLE_TABLE, old_day)
        assert (
            conn.execute(
                "SELECT count(*) FROM telemetry_sample_default WHERE drone_id = %s", (pk,)
            ).fetchone()[0]
            == 0
        )
        partition = storage.partition_name(storage.SAMPLE_TABLE, old_day)
        assert conn.execute(f"SELECT count(*) FROM {partition}").fetchone()[0] == len(samples)

        result = storage.maintain(
            conn, today=today, days_ahead=2, retention=storage.Retention(3, 30, 365)
        )

        days = _partition_days(conn, storage.SAMPLE_TABLE)
        assert {today, today + timedelta(days=1), today + timedelta(days=2)} <= days
        assert old_day not in days
        assert old_day in result["rolled_up"]
        assert "telemetry_sample_p20310605" in result["dropped"]
        # The aggregates stand in for the dropped samples, and agree with numpy.
        rolled = queries.query_range(
            pk,
            "BaroAltitude",
            ["Pressure"],
            start,
            start + timedelta(minutes=3),
            points=6,
            source="1s",
        )
        expected = _numpy_buckets(us, pressure, np.ones(len(us), bool), start, rolled.bucket)
        assert rolled.count == [c[3] for c in expected.values()]
        for i, (lo, hi, avg, _) in enumerate(expected.values()):
            assert rolled.series["Pressure"].min[i] == pytest.approx(lo)
            assert rolled.series["Pressure"].max[i] == pytest.approx(hi)
            assert rolled.series["Pressure"].avg[i] == pytest.approx(avg)
        by_minute = queries.query_range(
            pk,
            "BaroAltitude",
            ["Pressure"],
            start,
            start + timedelta(minutes=3),
            points=3,
            source="1m",
        )
        minutes = _numpy_buckets(us, pressure, np.ones(len(us), bool), start, by_minute.bucket)
        assert by_minute.count == [c[3] for c in minutes.values()]
        assert by_minute.series["Pressure"].avg == pytest.approx([c[2] for c in minutes.values()])
    finally:
        for table in storage.PERIODS:
            for name, day in storage.partitions(conn, table):
                if day.year == 2031:
                    storage.drop_partition(conn, table, name)
        conn.execute("DELETE FROM telemetry_rollup_done WHERE day >= '2031-01-01'")


def test_the_beat_task_creates_todays_and_tomorrows_partitions(world):
    from django.db import connection

    from telemetry.tasks import maintain_partitions

    result = maintain_partitions()
    connection.ensure_connection()
    days = _partition_days(connection.connection, storage.SAMPLE_TABLE)
    today = datetime.now(UTC).date()
    assert {today, today + timedelta(days=1)} <= days
    assert isinstance(result["created"], list)

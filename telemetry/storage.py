"""Telemetry storage: partition maintenance, COPY of sample batches, rollups and retention.

Plain psycopg 3, no Django, so the ingest process and the tests' private PostgreSQL use
the same code as the web app. Every function takes an open connection and commits what it
did itself, except `copy_samples` and `copy_rows`, whose caller decides when a batch is
committed.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta

import psycopg
from psycopg import sql

log = logging.getLogger(__name__)

SAMPLE_TABLE = "telemetry_sample"
ROLLUP_1S_TABLE = "telemetry_rollup_1s"
ROLLUP_1M_TABLE = "telemetry_rollup_1m"


def split_fields(fields: dict) -> tuple[dict, dict | None]:
    """(numbers, everything else or None): numbers go to `fields`, the rest to `labels`.

    Keeping only numbers in `fields` lets range queries cast `fields->>'X'` to float8
    without a per-row type check (migration 0002 has the measurement).
    """
    numbers: dict = {}
    labels: dict | None = None
    for name, value in fields.items():
        if type(value) is float or type(value) is int:  # bool is an int subclass: a label
            numbers[name] = value
        else:
            if labels is None:
                labels = {}
            labels[name] = value
    return numbers, labels


# One encoder for every row: json.dumps with options builds a new one per call.
_encode_json = json.JSONEncoder(separators=(",", ":")).encode


def _copy_json(value: dict) -> str:
    # JSON from the encoder has no raw tabs or newlines; only backslashes need doubling.
    return _encode_json(value).replace("\\", "\\\\")


@dataclass(frozen=True)
class Sample:
    """One flight-controller object as stored: its time, drone (pk), name and fields."""

    ts: float
    drone_pk: int
    object: str
    fields: dict

    def copy_line(self) -> str:
        return copy_line(self.ts, self.drone_pk, self.object, self.fields)


def copy_line(ts: float, drone_pk: int, object_name: str, fields: dict) -> str:
    """One sample as a line of COPY text format (tab-separated, backslash-escaped)."""
    stamp = datetime.fromtimestamp(ts, UTC).isoformat()
    numbers, labels = split_fields(fields)
    extra = _copy_json(labels) if labels else "\\N"
    return f"{stamp}\t{drone_pk}\t{object_name}\t{_copy_json(numbers)}\t{extra}\n"


COPY_COLUMNS = "(ts, drone_id, object, fields, labels)"


# ---------------------------------------------------------------------------------------
# Partitions


@dataclass(frozen=True)
class Period:
    """How a table is partitioned: daily (raw, 1 s) or monthly (1 min)."""

    monthly: bool

    def start(self, day: date) -> date:
        return day.replace(day=1) if self.monthly else day

    def next(self, start: date) -> date:
        if not self.monthly:
            return start + timedelta(days=1)
        return (start.replace(day=28) + timedelta(days=4)).replace(day=1)

    def suffix(self, start: date) -> str:
        return start.strftime("%Y%m" if self.monthly else "%Y%m%d")


PERIODS = {
    SAMPLE_TABLE: Period(monthly=False),
    ROLLUP_1S_TABLE: Period(monthly=False),
    ROLLUP_1M_TABLE: Period(monthly=True),
}
TIME_COLUMN = {SAMPLE_TABLE: "ts", ROLLUP_1S_TABLE: "bucket", ROLLUP_1M_TABLE: "bucket"}


def partition_name(table: str, day: date) -> str:
    period = PERIODS[table]
    return f"{table}_p{period.suffix(period.start(day))}"


def partitions(conn: psycopg.Connection, table: str) -> list[tuple[str, date]]:
    """The dated partitions of a table (default excluded), oldest first."""
    rows = conn.execute(
        """
        SELECT c.relname FROM pg_inherits i
        JOIN pg_class c ON c.oid = i.inhrelid
        JOIN pg_class p ON p.oid = i.inhparent
        WHERE p.relname = %s AND c.relname LIKE %s
        """,
        (table, f"{table}\\_p%"),
    ).fetchall()
    out = []
    for (name,) in rows:
        suffix = name.rsplit("_p", 1)[1]
        fmt = "%Y%m" if len(suffix) == 6 else "%Y%m%d"
        out.append((name, datetime.strptime(suffix, fmt).date()))
    return sorted(out, key=lambda item: item[1])


def ensure_partition(conn: psycopg.Connection, table: str, day: date) -> bool:
    """Create the partition holding `day` if missing; True if it was created.

    Rows that already landed in the default partition for that range are moved into the
    new partition in the same transaction, since PostgreSQL refuses to attach a range the
    default partition still holds rows for.
    """
    period = PERIODS[table]
    start = period.start(day)
    end = period.next(start)
    name = partition_name(table, start)
    column = TIME_COLUMN[table]
    with conn.transaction():
        exists = conn.execute("SELECT to_regclass(%s) IS NOT NULL", (name,)).fetchone()[0]
        if exists:
            return False
        # Serialise concurrent creators (beat task and ingest processes) on the parent.
        conn.execute(
            sql.SQL("LOCK TABLE {} IN SHARE UPDATE EXCLUSIVE MODE").format(sql.Identifier(table))
        )
        if conn.execute("SELECT to_regclass(%s) IS NOT NULL", (name,)).fetchone()[0]:
            return False
        bounds = (
            datetime.combine(start, datetime.min.time(), UTC),
            datetime.combine(end, datetime.min.time(), UTC),
        )
        conn.execute(
            sql.SQL("CREATE TABLE {} (LIKE {} INCLUDING DEFAULTS)").format(
                sql.Identifier(name), sql.Identifier(table)
            )
        )
        conn.execute(
            sql.SQL(
                "WITH moved AS (DELETE FROM {default} WHERE {col} >= %s AND {col} < %s "
                "RETURNING *) INSERT INTO {part} SELECT * FROM moved"
            ).format(
                default=sql.Identifier(f"{table}_default"),
                col=sql.Identifier(column),
                part=sql.Identifier(name),
            ),
            bounds,
        )
        conn.execute(
            # DDL takes no bind parameters: the bounds go in as quoted literals.
            sql.SQL("ALTER TABLE {} ATTACH PARTITION {} FOR VALUES FROM ({}) TO ({})").format(
                sql.Identifier(table),
                sql.Identifier(name),
                sql.Literal(bounds[0].isoformat()),
                sql.Literal(bounds[1].isoformat()),
            )
        )
    log.info("created partition %s", name)
    return True


def ensure_partitions_ahead(conn: psycopg.Connection, *, today: date, days_ahead: int) -> list[str]:
    """Partitions for today and the next `days_ahead` days on every table; names created."""
    created = []
    for table in PERIODS:
        for offset in range(days_ahead + 1):
            day = today + timedelta(days=offset)
            if ensure_partition(conn, table, day):
                created.append(partition_name(table, day))
    return created


def drop_partition(conn: psycopg.Connection, table: str, name: str) -> None:
    """Detach and drop one partition: retention without DELETE."""
    with conn.transaction():
        conn.execute(
            sql.SQL("ALTER TABLE {} DETACH PARTITION {}").format(
                sql.Identifier(table), sql.Identifier(name)
            )
        )
        conn.execute(sql.SQL("DROP TABLE {}").format(sql.Identifier(name)))
    log.info("dropped partition %s", name)


def drop_partitions_before(conn: psycopg.Connection, table: str, cutoff: date) -> list[str]:
    """Drop every partition of `table` that ends on or before `cutoff`; names dropped."""
    period = PERIODS[table]
    dropped = []
    for name, start in partitions(conn, table):
        if period.next(start) <= cutoff:
            drop_partition(conn, table, name)
            dropped.append(name)
    return dropped


# ---------------------------------------------------------------------------------------
# Writing samples


def copy_samples(conn: psycopg.Connection, samples: Sequence[Sample]) -> None:
    """COPY a batch into the sample table inside the caller's transaction."""
    with conn.cursor() as cursor:
        copy_rows(cursor, "".join(s.copy_line() for s in samples), idempotent=False)


def copy_rows(cursor: psycopg.Cursor, text: str, *, idempotent: bool) -> None:
    """COPY rows (COPY text lines, `Sample.copy_line`) into the sample table inside the
    caller's transaction. `idempotent` goes through a temporary table and skips rows
    already stored: after a failure whose outcome is unknown (the connection died around
    COMMIT), a batch that did commit is not stored twice."""
    if not idempotent:
        with cursor.copy(f"COPY {SAMPLE_TABLE} {COPY_COLUMNS} FROM STDIN") as copy:
            copy.write(text)
        return
    cursor.execute(
        "CREATE TEMP TABLE IF NOT EXISTS telemetry_stage "
        f"(LIKE {SAMPLE_TABLE}) ON COMMIT DELETE ROWS"
    )
    with cursor.copy(f"COPY telemetry_stage {COPY_COLUMNS} FROM STDIN") as copy:
        copy.write(text)
    cursor.execute(
        f"INSERT INTO {SAMPLE_TABLE} SELECT * FROM telemetry_stage "
        "ON CONFLICT (drone_id, object, ts) DO NOTHING"
    )


def insert_samples_row_by_row(conn: psycopg.Connection, samples: Iterable[Sample]) -> None:
    """The naive connector, one INSERT per object: kept as the benchmark's baseline."""
    with conn.cursor() as cursor:
        for s in samples:
            numbers, labels = split_fields(s.fields)
            cursor.execute(
                "INSERT INTO telemetry_sample (ts, drone_id, object, fields, labels) "
                "VALUES (to_timestamp(%s), %s, %s, %s::jsonb, %s::jsonb)",
                (
                    s.ts,
                    s.drone_pk,
                    s.object,
                    json.dumps(numbers),
                    json.dumps(labels) if labels else None,
                ),
            )
            conn.commit()


# ---------------------------------------------------------------------------------------
# Rollups and retention

_ROLLUP_SQL = """
INSERT INTO {target} (bucket, drone_id, object, field, n, min, max, avg)
SELECT date_bin(%(width)s, s.ts, TIMESTAMPTZ '2000-01-01'), s.drone_id, s.object, f.key,
       count(*), min(f.value::text::float8), max(f.value::text::float8),
       avg(f.value::text::float8)
FROM telemetry_sample s, jsonb_each(s.fields) f
WHERE s.ts >= %(start)s AND s.ts < %(end)s AND jsonb_typeof(f.value) = 'number'
GROUP BY 1, 2, 3, 4
ON CONFLICT (drone_id, object, field, bucket) DO UPDATE
SET n = EXCLUDED.n, min = EXCLUDED.min, max = EXCLUDED.max, avg = EXCLUDED.avg
"""


def rollup_day(conn: psycopg.Connection, day: date) -> None:
    """Aggregate one day of numeric fields into 1-second and 1-minute min/max/avg buckets."""
    start = datetime.combine(day, datetime.min.time(), UTC)
    params = {"start": start, "end": start + timedelta(days=1)}
    with conn.transaction():
        for table in (ROLLUP_1S_TABLE, ROLLUP_1M_TABLE):
            ensure_partition(conn, table, day)
        for table, width in ((ROLLUP_1S_TABLE, "1 second"), (ROLLUP_1M_TABLE, "1 minute")):
            conn.execute(
                sql.SQL(_ROLLUP_SQL).format(target=sql.Identifier(table)),
                {**params, "width": timedelta(seconds=1 if width == "1 second" else 60)},
            )
        conn.execute(
            "INSERT INTO telemetry_rollup_done (day) VALUES (%s) ON CONFLICT DO NOTHING", (day,)
        )


def rollup_pending(conn: psycopg.Connection, *, today: date) -> list[date]:
    """Roll up every finished day (before yesterday, so late samples are in) not yet done."""
    done = {row[0] for row in conn.execute("SELECT day FROM telemetry_rollup_done")}
    days = [
        start
        for _, start in partitions(conn, SAMPLE_TABLE)
        if start < today - timedelta(days=1) and start not in done
    ]
    for day in days:
        rollup_day(conn, day)
    return days


@dataclass(frozen=True)
class Retention:
    raw_days: int
    rollup_1s_days: int
    rollup_1m_days: int


def maintain(
    conn: psycopg.Connection, *, today: date, days_ahead: int, retention: Retention
) -> dict[str, list]:
    """The hourly job: partitions ahead, rollups of finished days, then drop expired ones.

    Raw partitions are dropped only once rolled up, so no day loses its aggregates.
    """
    created = ensure_partitions_ahead(conn, today=today, days_ahead=days_ahead)
    rolled = rollup_pending(conn, today=today)
    done = {row[0] for row in conn.execute("SELECT day FROM telemetry_rollup_done")}
    raw_cutoff = today - timedelta(days=retention.raw_days)
    dropped = []
    for name, start in partitions(conn, SAMPLE_TABLE):
        if start + timedelta(days=1) <= raw_cutoff and start in done:
            drop_partition(conn, SAMPLE_TABLE, name)
            dropped.append(name)
    dropped += drop_partitions_before(
        conn, ROLLUP_1S_TABLE, today - timedelta(days=retention.rollup_1s_days)
    )
    dropped += drop_partitions_before(
        conn, ROLLUP_1M_TABLE, today - timedelta(days=retention.rollup_1m_days)
    )
    return {"created": created, "rolled_up": rolled, "dropped": dropped}

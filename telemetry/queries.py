"""Reading telemetry: latest values, downsampled ranges and CSV export.

Functions take a drone's primary key; checking that the caller may see that drone is the
view's job (`Drone.objects.for_user`). Ranges are bucketed in SQL with `date_bin`, so a
day of 10 Hz samples leaves the database as ~1 000 rows.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta

import psycopg
from django.conf import settings
from django.db import connection, transaction
from psycopg import sql

# Each bucket at least this wide: timestamps are stored to the microsecond, and a
# 1 ms bucket already splits 10 Hz data into single samples.
MIN_BUCKET = timedelta(milliseconds=1)


def conninfo_from_settings() -> str:
    """A libpq connection string for the database Django uses (its test one under pytest)."""
    db = connection.settings_dict
    parts = {
        "dbname": db["NAME"],
        "user": db.get("USER") or "",
        "password": db.get("PASSWORD") or "",
        "host": db.get("HOST") or "127.0.0.1",
        "port": str(db.get("PORT") or 5432),
    }
    return psycopg.conninfo.make_conninfo(**{k: v for k, v in parts.items() if v})


def _cursor():  # type: ignore[no-untyped-def]
    connection.ensure_connection()
    return connection.connection.cursor()


# ---------------------------------------------------------------------------------------
# Latest values

_LATEST_SQL = """
WITH RECURSIVE objects AS (
    (SELECT object FROM telemetry_sample WHERE drone_id = %(drone)s ORDER BY object LIMIT 1)
    UNION ALL
    SELECT (SELECT s.object FROM telemetry_sample s
            WHERE s.drone_id = %(drone)s AND s.object > o.object ORDER BY s.object LIMIT 1)
    FROM objects o WHERE o.object IS NOT NULL
)
SELECT last.object, extract(epoch FROM last.ts)::float8, last.fields
FROM objects o
CROSS JOIN LATERAL (
    SELECT s.object, s.ts, s.fields || coalesce(s.labels, '{}') AS fields FROM telemetry_sample s
    WHERE s.drone_id = %(drone)s AND s.object = o.object
    ORDER BY s.ts DESC LIMIT 1
) last
WHERE o.object IS NOT NULL
"""


def latest(drone_pk: int, objects: Sequence[str] | None = None) -> dict[str, dict]:
    """`{object: {"ts": epoch, "fields": {...}}}`: each object's most recent sample.

    A loose index scan over (drone, object, ts): one index probe per object, however
    much history there is.
    """
    with _cursor() as cursor:
        if objects:
            cursor.execute(
                """
                SELECT last.object, extract(epoch FROM last.ts)::float8, last.fields
                FROM unnest(%(objects)s::text[]) o(object)
                CROSS JOIN LATERAL (
                    SELECT s.object, s.ts, s.fields || coalesce(s.labels, '{}') AS fields
                    FROM telemetry_sample s
                    WHERE s.drone_id = %(drone)s AND s.object = o.object
                    ORDER BY s.ts DESC LIMIT 1
                ) last
                """,
                {"drone": drone_pk, "objects": list(objects)},
            )
        else:
            cursor.execute(_LATEST_SQL, {"drone": drone_pk})
        return {name: {"ts": ts, "fields": _json(fields)} for name, ts, fields in cursor.fetchall()}


def latest_for_drones(drone_pks: Sequence[int], objects: Sequence[str]) -> dict[int, dict]:
    """`{drone_pk: {object: {"ts", "fields"}}}` for an overview of many drones."""
    if not drone_pks:
        return {}
    with _cursor() as cursor:
        cursor.execute(
            """
            SELECT d.pk, last.object, extract(epoch FROM last.ts)::float8, last.fields
            FROM unnest(%(drones)s::bigint[]) d(pk)
            CROSS JOIN unnest(%(objects)s::text[]) o(object)
            CROSS JOIN LATERAL (
                SELECT s.object, s.ts, s.fields || coalesce(s.labels, '{}') AS fields
                FROM telemetry_sample s
                WHERE s.drone_id = d.pk AND s.object = o.object
                ORDER BY s.ts DESC LIMIT 1
            ) last
            """,
            {"drones": list(drone_pks), "objects": list(objects)},
        )
        out: dict[int, dict] = {pk: {} for pk in drone_pks}
        for pk, name, ts, fields in cursor.fetchall():
            out[pk][name] = {"ts": ts, "fields": _json(fields)}
        return out


def _json(value: object) -> dict:
    # Django's connection loads jsonb as text (its JSONField decodes); plain psycopg as dict.
    return json.loads(value) if isinstance(value, str) else value  # type: ignore[return-value]


# ---------------------------------------------------------------------------------------
# Ranges


@dataclass
class Series:
    min: list[float | None] = field(default_factory=list)
    max: list[float | None] = field(default_factory=list)
    avg: list[float | None] = field(default_factory=list)


@dataclass
class Range:
    """Columnar buckets, ready for a chart: `t[i]` is the start of bucket i (epoch s)."""

    object: str
    start: datetime
    end: datetime
    bucket: timedelta
    source: str
    t: list[float]
    count: list[int]
    series: dict[str, Series]

    def to_dict(self) -> dict:
        return {
            "object": self.object,
            "start": self.start.timestamp(),
            "end": self.end.timestamp(),
            "bucket_s": self.bucket.total_seconds(),
            "source": self.source,
            "t": self.t,
            "count": self.count,
            "series": {
                name: {"min": s.min, "max": s.max, "avg": s.avg} for name, s in self.series.items()
            },
        }


def bucket_width(start: datetime, end: datetime, points: int) -> timedelta:
    """The narrowest whole-millisecond bucket that cuts [start, end) into at most `points`."""
    span_ms = (end - start) / timedelta(milliseconds=1)
    return max(MIN_BUCKET, timedelta(milliseconds=math.ceil(span_ms / max(points, 1))))


def source_for(start: datetime, bucket: timedelta, now: datetime | None = None) -> str:
    """Raw samples while they are kept, else the finest aggregate that still covers start."""
    now = now or datetime.now(UTC)
    if start >= now - timedelta(days=settings.TELEMETRY_RAW_RETENTION_DAYS):
        return "raw"
    if bucket < timedelta(minutes=1) and start >= now - timedelta(
        days=settings.TELEMETRY_1S_RETENTION_DAYS
    ):
        return "1s"
    return "1m"


def query_range(
    drone_pk: int,
    object_name: str,
    fields: Sequence[str],
    start: datetime,
    end: datetime,
    points: int = 1000,
    source: str | None = None,
) -> Range:
    """min/max/avg of each numeric field in at most `points` equal buckets from `start`."""
    bucket = bucket_width(start, end, points)
    source = source or source_for(start, bucket)
    params = {
        "drone": drone_pk,
        "object": object_name,
        "start": start,
        "end": end,
        "width": bucket,
        "fields": list(fields),
    }
    result = Range(
        object_name, start, end, bucket, source, [], [], {name: Series() for name in fields}
    )
    if source == "raw":
        _fill_from_raw(result, fields, params)
    else:
        table = "telemetry_rollup_1s" if source == "1s" else "telemetry_rollup_1m"
        _fill_from_rollup(result, fields, params, table)
    return result


def _fill_from_raw(result: Range, fields: Sequence[str], params: dict) -> None:
    """Bucket the raw samples: one row per bucket, min/max/avg of every field side by side."""
    values = sql.SQL(", ").join(
        sql.SQL("(fields->>{})::float8 AS {}").format(sql.Literal(name), sql.Identifier(f"v{i}"))
        for i, name in enumerate(fields)
    )
    aggregates = sql.SQL(", ").join(
        sql.SQL("{agg}({v})").format(agg=sql.SQL(agg), v=sql.Identifier(f"v{i}"))
        for i in range(len(fields))
        for agg in ("min", "max", "avg")
    )
    # `fields` holds only numbers (migration 0002), so the cast cannot fail. OFFSET 0
    # keeps the subquery whole: otherwise each aggregate re-extracts its field.
    query = sql.SQL(
        "SELECT extract(epoch FROM b)::float8, count(*), {aggregates} FROM ("
        "SELECT date_bin(%(width)s, ts, %(start)s) AS b, {values} FROM telemetry_sample "
        "WHERE drone_id = %(drone)s AND object = %(object)s "
        "AND ts >= %(start)s AND ts < %(end)s OFFSET 0) s GROUP BY b ORDER BY b"
    ).format(aggregates=aggregates, values=values)
    with transaction.atomic(), _cursor() as cursor:
        # JIT compiling this one-pass aggregate costs more (~150 ms) than it saves.
        cursor.execute("SET LOCAL jit = off")
        cursor.execute(query, params)
        rows = cursor.fetchall()
    for row in rows:
        result.t.append(row[0])
        result.count.append(row[1])
        for i, name in enumerate(fields):
            s = result.series[name]
            s.min.append(row[2 + 3 * i])
            s.max.append(row[3 + 3 * i])
            s.avg.append(row[4 + 3 * i])


def _fill_from_rollup(result: Range, fields: Sequence[str], params: dict, table: str) -> None:
    """Re-bucket a rollup: counts add up, the average is weighted by each row's count."""
    query = sql.SQL(
        "SELECT extract(epoch FROM date_bin(%(width)s, bucket, %(start)s))::float8 AS b, field, "
        "sum(n), min(min), max(max), sum(avg * n) / sum(n) FROM {table} "
        "WHERE drone_id = %(drone)s AND object = %(object)s AND field = ANY(%(fields)s) "
        "AND bucket >= %(start)s AND bucket < %(end)s GROUP BY b, field ORDER BY b"
    ).format(table=sql.Identifier(table))
    with _cursor() as cursor:
        cursor.execute(query, params)
        rows = cursor.fetchall()
    by_bucket: dict[float, dict[str, tuple]] = {}
    for b, name, n, lo, hi, avg in rows:
        by_bucket.setdefault(b, {})[name] = (n, lo, hi, avg)
    for b in sorted(by_bucket):
        values = by_bucket[b]
        result.t.append(b)
        result.count.append(max(int(v[0]) for v in values.values()))
        for name in fields:
            _, lo, hi, avg = values.get(name, (0, None, None, None))
            result.series[name].min.append(lo)
            result.series[name].max.append(hi)
            result.series[name].avg.append(avg)


# ---------------------------------------------------------------------------------------
# CSV export


EXPORT_WHERE = "drone_id = %(drone)s AND ts >= %(start)s AND ts < %(end)s"


def export_columns(
    conninfo: str, drone_pk: int, start: datetime, end: datetime, object_name: str | None = None
) -> list[tuple[str, str]]:
    """(object, field) of every field stored in the range, sorted: the wide CSV's columns."""
    where = EXPORT_WHERE + (" AND object = %(object)s" if object_name else "")
    params = {"drone": drone_pk, "start": start, "end": end, "object": object_name}
    with psycopg.connect(conninfo) as conn:
        rows = conn.execute(
            "SELECT DISTINCT object, jsonb_object_keys(fields || coalesce(labels, '{}')) "
            f"FROM telemetry_sample WHERE {where} ORDER BY 1, 2",
            params,
        ).fetchall()
    return [(str(name), str(field)) for name, field in rows]


def export_csv(
    conninfo: str,
    drone_pk: int,
    start: datetime,
    end: datetime,
    object_name: str | None = None,
    fields: Sequence[str] = (),
    chunk_rows: int = 5000,
    layout: str = "wide",
) -> Iterator[str]:
    """CSV text in chunks, from a server-side cursor, so a long range never sits in memory.

    "wide" (the default): one column per field (arrays as JSON), the given `fields` or
    every field stored in the range; columns are `Object.field` unless one object is
    asked for. "long": ts, object and all fields as one JSON column.
    """
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    columns: list[tuple[str | None, str]] = []
    if layout == "wide":
        columns = [(object_name, f) for f in fields] or list(
            export_columns(conninfo, drone_pk, start, end, object_name)
        )
    if layout == "long":
        writer.writerow(["ts", "object", "fields"])
    elif object_name:
        writer.writerow(["ts", *(f for _, f in columns)])
    else:
        writer.writerow(["ts", "object", *(f"{o}.{f}" for o, f in columns)])
    yield buffer.getvalue()
    rows = _export_rows(conninfo, drone_pk, start, end, object_name, chunk_rows)
    for chunk in rows:
        buffer.seek(0)
        buffer.truncate()
        for ts, name, values in chunk:
            stamp = ts.astimezone(UTC).isoformat()
            if layout == "long":
                writer.writerow([stamp, name, json.dumps(values, separators=(",", ":"))])
                continue
            cells = [_cell(values.get(f)) if o in (None, name) else "" for o, f in columns]
            writer.writerow([stamp, *cells] if object_name else [stamp, name, *cells])
        yield buffer.getvalue()


def _export_rows(
    conninfo: str,
    drone_pk: int,
    start: datetime,
    end: datetime,
    object_name: str | None,
    chunk_rows: int,
) -> Iterator[list[tuple]]:
    where = EXPORT_WHERE + (" AND object = %(object)s" if object_name else "")
    params = {"drone": drone_pk, "start": start, "end": end, "object": object_name}
    with psycopg.connect(conninfo) as conn, conn.cursor(name="telemetry_export") as cursor:
        cursor.itersize = chunk_rows
        cursor.execute(
            "SELECT ts, object, fields || coalesce(labels, '{}') FROM telemetry_sample "
            f"WHERE {where} ORDER BY ts, object",
            params,
        )
        while rows := cursor.fetchmany(chunk_rows):
            yield rows


def _cell(value: object) -> object:
    if value is None:
        return ""
    if isinstance(value, list | dict):
        return json.dumps(value, separators=(",", ":"))
    return value

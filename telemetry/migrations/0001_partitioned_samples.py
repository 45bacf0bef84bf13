"""Telemetry samples and their aggregates as range-partitioned tables (raw SQL).

Django cannot declare partitioned tables, so this migration is SQL. The default partitions
catch rows no daily partition covers yet, so an insert never fails; `telemetry.storage`
creates the daily partitions ahead and moves stray rows out of the default.
No foreign key to fleet_drone: checking one per row would cost the ingest its speed, and
samples outlive their drones until retention drops them.
"""

from django.db import migrations

SQL = """
CREATE TABLE telemetry_sample (
    ts timestamptz NOT NULL,
    drone_id bigint NOT NULL,
    object text NOT NULL,
    fields jsonb NOT NULL
) PARTITION BY RANGE (ts);
CREATE TABLE telemetry_sample_default PARTITION OF telemetry_sample DEFAULT;
CREATE INDEX telemetry_sample_ts_brin ON telemetry_sample USING brin (ts);
-- Unique so that a retried batch can be re-sent with ON CONFLICT DO NOTHING.
CREATE UNIQUE INDEX telemetry_sample_drone_object_ts
    ON telemetry_sample (drone_id, object, ts);

CREATE TABLE telemetry_rollup_1s (
    bucket timestamptz NOT NULL,
    drone_id bigint NOT NULL,
    object text NOT NULL,
    field text NOT NULL,
    n integer NOT NULL,
    min double precision NOT NULL,
    max double precision NOT NULL,
    avg double precision NOT NULL
) PARTITION BY RANGE (bucket);
CREATE TABLE telemetry_rollup_1s_default PARTITION OF telemetry_rollup_1s DEFAULT;
CREATE UNIQUE INDEX telemetry_rollup_1s_key
    ON telemetry_rollup_1s (drone_id, object, field, bucket);

CREATE TABLE telemetry_rollup_1m (LIKE telemetry_rollup_1s) PARTITION BY RANGE (bucket);
CREATE TABLE telemetry_rollup_1m_default PARTITION OF telemetry_rollup_1m DEFAULT;
CREATE UNIQUE INDEX telemetry_rollup_1m_key
    ON telemetry_rollup_1m (drone_id, object, field, bucket);

-- Days whose raw samples have been aggregated, so the rollup runs once per day.
CREATE TABLE telemetry_rollup_done (
    day date PRIMARY KEY,
    done_at timestamptz NOT NULL DEFAULT now()
);
"""

REVERSE_SQL = """
DROP TABLE IF EXISTS telemetry_rollup_done;
DROP TABLE IF EXISTS telemetry_rollup_1m;
DROP TABLE IF EXISTS telemetry_rollup_1s;
DROP TABLE IF EXISTS telemetry_sample;
"""


class Migration(migrations.Migration):
    initial = True
    dependencies: list = []
    operations = [migrations.RunSQL(SQL, REVERSE_SQL)]

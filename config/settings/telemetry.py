"""Telemetry: what is stored, for how long, and how fast it is written and pushed."""

from __future__ import annotations

from config.env import env

# Raw samples are kept this many days, then only the 1-second and 1-minute aggregates.
TELEMETRY_RAW_RETENTION_DAYS = env.int("TELEMETRY_RAW_RETENTION_DAYS", 14)
TELEMETRY_1S_RETENTION_DAYS = env.int("TELEMETRY_1S_RETENTION_DAYS", 90)
TELEMETRY_1M_RETENTION_DAYS = env.int("TELEMETRY_1M_RETENTION_DAYS", 730)
# Daily partitions are created this many days ahead by the beat task.
TELEMETRY_PARTITIONS_AHEAD_DAYS = env.int("TELEMETRY_PARTITIONS_AHEAD_DAYS", 3)
# The ingest process flushes a COPY batch at this many rows or this often, whichever first.
TELEMETRY_FLUSH_ROWS = env.int("TELEMETRY_FLUSH_ROWS", 5000)
TELEMETRY_FLUSH_INTERVAL_S = env.float("TELEMETRY_FLUSH_INTERVAL_S", 0.2)
# Rows held in memory while the database is away; beyond this, messages are counted as overflow.
TELEMETRY_BUFFER_ROWS = env.int("TELEMETRY_BUFFER_ROWS", 500_000)
TELEMETRY_MAX_MESSAGE_BYTES = env.int("TELEMETRY_MAX_MESSAGE_BYTES", 256 * 1024)
# Accepted object timestamps relative to the ground's clock.
TELEMETRY_MAX_PAST_S = env.float("TELEMETRY_MAX_PAST_S", 7 * 86400)
TELEMETRY_MAX_FUTURE_S = env.float("TELEMETRY_MAX_FUTURE_S", 300)
# Live values pushed to dashboards at most this often per drone.
TELEMETRY_LIVE_HZ = env.float("TELEMETRY_LIVE_HZ", 5)

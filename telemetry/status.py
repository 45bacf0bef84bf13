"""The ingest process's counters as the status page and API show them."""

from __future__ import annotations

import time

import redis

from workers.counters import snapshot

# The ingest writer reports at least every flush interval; silent longer means stopped.
ALIVE_WITHIN_S = 5.0


def ingest_status() -> dict:
    """Counters of the `ingest` process(es): totals, dropped by reason, lag, rate, alive."""
    try:
        counters = snapshot().get("ingest", {})
    except redis.RedisError as exc:
        return {"available": False, "error": str(exc)}
    dropped = {
        name.split(".", 1)[1]: int(value)
        for name, value in sorted(counters.items())
        if name.startswith("dropped.")
    }
    alive_at = counters.get("alive_at")
    return {
        "available": True,
        "alive": bool(alive_at and time.time() - alive_at < ALIVE_WITHIN_S),
        "received_messages": int(counters.get("received", 0)),
        "received_objects": int(counters.get("objects_received", 0)),
        "stored_objects": int(counters.get("stored", 0)),
        "dropped_messages": dropped,
        "dropped_total": sum(dropped.values()),
        "overflow_messages": int(counters.get("overflow", 0)),
        "database_errors": int(counters.get("db_errors", 0)),
        "rate_objects_per_s": counters.get("rate_objects_per_s", 0.0),
        "lag_s": counters.get("lag_s"),
        "buffer_rows": int(counters.get("buffer_rows", 0)),
        "updated_at": counters.get("updated_at"),
    }

"""The ingest process's counters as the status page and API show them."""

from __future__ import annotations

import time

import redis

from workers.counters import instances, snapshot

# The ingest writer reports at least every flush interval; silent longer means stopped.
ALIVE_WITHIN_S = 5.0


def ingest_status() -> dict:
    """Counters of the `ingest` process(es): totals, dropped by reason, lag, rate, alive.

    Totals add up over every ingest process; lag is the worst of the live instances and
    the rate their sum, since with several ingests the last one to report says nothing
    about the others.
    """
    try:
        counters = snapshot().get("ingest", {})
        live = [i for i in instances() if i.process == "ingest" and i.alive]
    except redis.RedisError as exc:
        return {"available": False, "error": str(exc)}
    dropped = {
        name.split(".", 1)[1]: int(value)
        for name, value in sorted(counters.items())
        if name.startswith("dropped.")
    }
    now = time.time()
    writing = [i for i in live if now - i.counters.get("alive_at", 0) < ALIVE_WITHIN_S]
    alive_at = counters.get("alive_at")
    lags = [i.counters["lag_s"] for i in writing if "lag_s" in i.counters]
    return {
        "available": True,
        "alive": bool(writing) or bool(alive_at and now - alive_at < ALIVE_WITHIN_S),
        "instances_alive": len(writing),
        "received_messages": int(counters.get("received", 0)),
        "received_objects": int(counters.get("objects_received", 0)),
        "stored_objects": int(counters.get("stored", 0)),
        "dropped_messages": dropped,
        "dropped_total": sum(dropped.values()),
        "overflow_messages": int(counters.get("overflow", 0)),
        "database_errors": int(counters.get("db_errors", 0)),
        "rate_objects_per_s": (
            round(sum(i.counters.get("rate_objects_per_s", 0.0) for i in writing), 1)
            if writing
            else counters.get("rate_objects_per_s", 0.0)
        ),
        "lag_s": max(lags) if lags else counters.get("lag_s"),
        "buffer_rows": (
            int(sum(i.counters.get("buffer_rows", 0) for i in writing))
            if writing
            else int(counters.get("buffer_rows", 0))
        ),
        "updated_at": counters.get("updated_at"),
    }

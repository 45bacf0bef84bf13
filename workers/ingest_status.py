"""The ingest process's counters as the status page and API show them.

Here with the other readers of what long-running processes write (workers.counters): the
ingest process writes these counters, and pages of any app read them.
"""

from __future__ import annotations

import time

import redis

from workers.counters import OTHER_DRONES, instances, refusals, snapshot

# The ingest writer reports at least every flush interval; silent longer means stopped.
ALIVE_WITHIN_S = 5.0


def ingest_status() -> dict:
    """Counters of the `ingest` process(es): totals, dropped by reason, lag, rate, alive.

    Totals add up over every ingest process since Redis started; lag is the worst of the
    live instances and the rate and buffer their sums, since with several ingests the last
    one to report says nothing about the others, and a stopped one's gauges are stale.
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
    # Lag, rate and buffer are gauges: only live instances' values mean anything now.
    writing = [i for i in live if now - i.counters.get("alive_at", 0) < ALIVE_WITHIN_S]
    alive_at = counters.get("alive_at")
    lags = [i.counters["lag_s"] for i in live if "lag_s" in i.counters]
    return {
        "available": True,
        "alive": bool(writing) or bool(alive_at and now - alive_at < ALIVE_WITHIN_S),
        "instances_alive": len(live),
        "instances_writing": len(writing),
        "received_messages": int(counters.get("received", 0)),
        "received_objects": int(counters.get("objects_received", 0)),
        "stored_objects": int(counters.get("stored", 0)),
        "dropped_messages": dropped,
        "dropped_total": sum(dropped.values()),
        "overflow_messages": int(counters.get("overflow", 0)),
        "database_errors": int(counters.get("db_errors", 0)),
        "rate_objects_per_s": round(
            sum(i.counters.get("rate_objects_per_s", 0.0) for i in live), 1
        ),
        "lag_s": max(lags) if lags else None,
        "buffer_rows": int(sum(i.counters.get("buffer_rows", 0) for i in live)),
        "updated_at": counters.get("updated_at"),
    }


def drone_refusals(visible: set[str] | None = None, limit: int = 50) -> list[dict] | None:
    """Refused messages per drone and reason, every process's (gateway and ingest), the
    most refused drone first; only the `visible` drone ids unless None (every drone, and
    the ids past the cap as OTHER_DRONES). None when Redis cannot be read."""
    try:
        rows = refusals()
    except redis.RedisError:
        return None
    if visible is not None:
        rows = [row for row in rows if row["drone_id"] in visible]
    for row in rows:
        row["other"] = row["drone_id"] == OTHER_DRONES
    return rows[:limit]

"""What the ingest refuses, and a batch the database refuses costing only its bad rows."""

from __future__ import annotations

import json
import time

import psycopg
import pytest

from telemetry import storage
from telemetry.ingest import (
    Chunk,
    CounterSink,
    DroneMap,
    IngestConfig,
    Ingestor,
    Limits,
    Rejected,
    load_drone_ids,
    parse_message,
)
from telemetry.queries import conninfo_from_settings

NOW = time.time()


def _payload(fields: dict, ts: float = NOW) -> bytes:
    return json.dumps({"ts": NOW, "objects": [{"name": "Gyros", "ts": ts, "fields": fields}]})


UNSTORABLE = [
    (_payload({"mode": "a\x00b"}), "bad_text"),
    (_payload({"mode": "\udc00"}), "bad_text"),
    (_payload({"mode": "x" * 200_000}), "bad_value"),
    # A quoted placeholder: a number's digits could also be in the timestamp.
    (_payload({"x": "NOT_FINITE"}).replace('"NOT_FINITE"', "-Infinity"), "bad_value"),
    (_payload({"x": 1}, ts=1e30), "ts_window"),
    (_payload({"x": 1}, ts=-1e30), "ts_window"),
    (
        _payload({"x": 1}).replace(f'"ts": {NOW!r}, "objects"', '"ts": 1e30, "objects"'),
        "ts_window",
    ),
]


# Ids without the payloads: these carry the collection time, and parallel workers
# (pytest-xdist) must collect the same test names.
@pytest.mark.parametrize(
    ("payload", "reason"), UNSTORABLE, ids=[reason for _, reason in UNSTORABLE]
)
def test_unstorable_values_are_refused_with_their_reason(payload, reason):
    with pytest.raises(Rejected) as refused:
        parse_message(payload.encode(), now=NOW, limits=Limits(max_bytes=1 << 20))
    assert refused.value.reason == reason


def _chunk(drone_id: str, pk: int, fields: dict, ts: float) -> Chunk:
    return Chunk(
        received=time.monotonic(),
        rows=1,
        text=storage.copy_line(ts, pk, "Gyros", fields),
        days=frozenset({int(ts // 86400)}),
        drone=drone_id,
    )


def _stored(conninfo: str, pk: int) -> list[float]:
    with psycopg.connect(conninfo) as conn:
        rows = conn.execute(
            "SELECT (fields->>'x')::float8 FROM telemetry_sample WHERE drone_id = %s ORDER BY 1",
            (pk,),
        ).fetchall()
    return [x for (x,) in rows]


@pytest.mark.django_db(transaction=True)
def test_rows_the_database_refuses_are_dropped_alone_and_counted_against_their_drone(world_tx):
    """Rows that validation would have refused, put straight into a batch: the batch is
    halved until only they are left out, and every other drone's row is stored."""
    conninfo = conninfo_from_settings()
    good, hostile = world_tx.drone, world_tx.other_drone
    counters = CounterSink()
    ingestor = Ingestor(
        IngestConfig(conninfo=conninfo, mqtt_url="mqtt://ground:pw@127.0.0.1:1"),
        drones=DroneMap(lambda: load_drone_ids(conninfo)),
        counters=counters,
    )
    chunks = [_chunk(good.drone_id, good.pk, {"x": float(i)}, NOW - 10 + i) for i in range(7)]
    chunks.insert(2, _chunk(hostile.drone_id, hostile.pk, {"x": 1.0, "s": "a\x00"}, NOW))
    chunks.insert(6, _chunk(hostile.drone_id, hostile.pk, {"x": 2.0, "s": "\ud800"}, NOW))
    try:
        refused = ingestor._flush_once(chunks, retrying=False)
        ingestor._count_refused(refused)
    finally:
        ingestor._drop_connection()

    assert [c.drone for c in refused] == [hostile.drone_id] * 2
    assert _stored(conninfo, good.pk) == [float(i) for i in range(7)]
    assert _stored(conninfo, hostile.pk) == []
    assert counters.counts["stored"] == 7 and counters.counts["dropped.db_rejected"] == 2
    assert counters.refusals == {(hostile.drone_id, "telemetry.db_rejected"): 2}

"""The ingest acknowledges a QoS 1 telemetry message only once its rows are committed:
with the database down, the broker stops handing it more than its in-flight window
(Mosquitto's `max_inflight_messages`, 20) and keeps the rest; after recovery every
sample is stored once."""

from __future__ import annotations

import time

import psycopg
import pytest

from runtime.processes import wait_for
from telemetry.ingest import CounterSink, DroneMap, IngestConfig, Ingestor, load_drone_ids
from workers.mosquitto import start_broker

from .support import Publisher
from .test_database_restart import private_db  # noqa: F401 - the fixture

pytestmark = pytest.mark.e2e

INFLIGHT_WINDOW = 20  # Mosquitto's default max_inflight_messages
MESSAGES = 120


def _message(ts: float, seq: int) -> dict:
    fields = {"Roll": 0.1, "Pitch": -0.3, "Yaw": float(seq)}
    return {"ts": ts, "objects": [{"name": "AttitudeActual", "ts": ts, "fields": fields}]}


def test_qos1_telemetry_is_acknowledged_only_after_its_commit(private_db, tmp_path):  # noqa: F811
    broker = start_broker(tmp_path, {"ground": "g", "DRONE_A": "a"})
    counters = CounterSink()
    ingestor = Ingestor(
        IngestConfig(
            conninfo=private_db.conninfo, mqtt_url=broker.url_for("ground"), flush_interval=0.05
        ),
        drones=DroneMap(lambda: load_drone_ids(private_db.conninfo)),
        counters=counters,
    )
    ingestor.start()
    drone = Publisher(broker.url_for("DRONE_A"))
    try:
        assert ingestor.subscriber.subscribed.wait(10)
        start = time.time() - 60
        drone.publish("DRONE_A/telemetry/out", _message(start, 0), qos=1)
        assert wait_for(lambda: ingestor.stored == 1, 10)
        private_db.stop()
        for seq in range(1, MESSAGES + 1):
            drone.publish("DRONE_A/telemetry/out", _message(start + seq * 0.1, seq), qos=1)
        time.sleep(3)
        # Nothing committed, nothing acknowledged: the broker holds back the rest.
        received = counters.counts["received"]
        assert 1 < received <= 1 + INFLIGHT_WINDOW, received
        assert counters.counts.get("db_errors", 0) > 0
        private_db.start()
        assert wait_for(lambda: ingestor.stored >= MESSAGES + 1, 60), ingestor.stored
        with psycopg.connect(private_db.conninfo) as conn:
            rows, distinct = conn.execute(
                "SELECT count(*), count(DISTINCT ts) FROM telemetry_sample"
            ).fetchone()
        assert rows == distinct == MESSAGES + 1
    finally:
        drone.close()
        ingestor.stop(drain_timeout=5)
        broker.stop()

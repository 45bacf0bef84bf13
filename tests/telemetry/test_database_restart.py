"""PostgreSQL stopped for 10 s in the middle of ingest, then back: nothing is lost."""

from __future__ import annotations

import importlib
import threading
import time

import psycopg
import pytest

from runtime.processes import wait_for
from telemetry.ingest import CounterSink, DroneMap, IngestConfig, Ingestor, load_drone_ids
from workers.mosquitto import start_broker

from .private_postgres import start_private_postgres
from .support import Publisher, drone_messages

pytestmark = pytest.mark.e2e

# The telemetry migrations' own SQL, in order: the same schema as a migrated database.
SCHEMA = [
    importlib.import_module(f"telemetry.migrations.{name}").SQL
    for name in ("0001_partitioned_samples", "0002_labels_apart_from_numbers")
]


@pytest.fixture
def private_db():
    server = start_private_postgres()
    with psycopg.connect(server.conninfo, autocommit=True) as conn:
        # The ingest reads only these two columns of the fleet's table.
        conn.execute("CREATE TABLE fleet_drone (id bigserial PRIMARY KEY, drone_id text UNIQUE)")
        conn.execute("INSERT INTO fleet_drone (drone_id) VALUES ('DRONE_A'), ('DRONE_B')")
        for sql in SCHEMA:
            conn.execute(sql)
    yield server
    server.destroy()


def test_nothing_is_lost_when_postgres_is_down_for_ten_seconds(private_db, tmp_path):
    broker = start_broker(tmp_path, {"ground": "g", "DRONE_A": "a", "DRONE_B": "b"})
    counters = CounterSink()
    ingestor = Ingestor(
        IngestConfig(conninfo=private_db.conninfo, mqtt_url=broker.url_for("ground")),
        drones=DroneMap(lambda: load_drone_ids(private_db.conninfo)),
        counters=counters,
    )
    ingestor.start()
    time.sleep(0.5)
    published = {"DRONE_A": 0, "DRONE_B": 0}
    stop = threading.Event()

    def fly(drone_id: str, offset: float) -> None:
        drone = Publisher(broker.url_for(drone_id))
        # 20 s of telemetry sent over ~16 s, as two drones at 10 Hz would.
        for message in drone_messages(time.time() - 20 + offset, seconds=20):
            if stop.is_set():
                break
            drone.publish(f"{drone_id}/telemetry/out", message, qos=1)
            published[drone_id] += len(message["objects"])
            time.sleep(0.08)
        drone.close()

    pilots = [threading.Thread(target=fly, args=(d, i * 0.01)) for i, d in enumerate(published)]
    try:
        for pilot in pilots:
            pilot.start()
        time.sleep(2)
        private_db.stop()
        time.sleep(10)
        assert counters.counts.get("db_errors", 0) > 0
        assert ingestor.buffer.rows > 0
        private_db.start()
        for pilot in pilots:
            pilot.join(30)
        total = sum(published.values())
        assert wait_for(lambda: ingestor.stored >= total, 20)
        with psycopg.connect(private_db.conninfo) as conn:
            rows, distinct = conn.execute(
                "SELECT count(*), count(DISTINCT (drone_id, object, ts)) FROM telemetry_sample"
            ).fetchone()
        assert rows == distinct == total
        assert counters.counts.get("overflow", 0) == 0
    finally:
        stop.set()
        ingestor.stop(drain_timeout=5)
        broker.stop()

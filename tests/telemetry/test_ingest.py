"""The ingest process end to end: drones publish through a real broker, rows land once."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import psycopg
import pytest

from runtime.processes import wait_for
from telemetry.ingest import (
    CounterSink,
    DroneMap,
    IngestConfig,
    Ingestor,
    Limits,
    load_drone_ids,
)
from workers.mosquitto import start_broker

from .support import Publisher, drone_messages

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e


def _conninfo() -> str:
    from telemetry.queries import conninfo_from_settings

    return conninfo_from_settings()


def _stored(conninfo: str, drone_pk: int) -> tuple[int, int]:
    """(rows, distinct (object, ts)) stored for a drone."""
    with psycopg.connect(conninfo) as conn:
        return conn.execute(
            "SELECT count(*), count(DISTINCT (object, ts)) FROM telemetry_sample "
            "WHERE drone_id = %s",
            (drone_pk,),
        ).fetchone()


def _start_command(broker_url: str, db_name: str) -> tuple[subprocess.Popen, threading.Event]:
    env = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "config.settings.test",
        "TEST_WORKER_DB_NAME": db_name,
        "LOG_LEVEL": "INFO",
    }
    process = subprocess.Popen(
        [sys.executable, "manage.py", "ingest_telemetry", "--mqtt-url", broker_url, "--no-live"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    subscribed = threading.Event()
    lines: list[str] = []

    def read() -> None:
        for line in process.stdout:  # type: ignore[union-attr]
            lines.append(line)
            if "subscribed" in line:
                subscribed.set()

    threading.Thread(target=read, daemon=True).start()
    process.output = lines  # type: ignore[attr-defined]
    return process, subscribed


def test_every_object_a_drone_publishes_is_stored_exactly_once(world_tx, tmp_path):
    from django.db import connection

    broker = start_broker(tmp_path, {"ground": "ground-pw", "ACME_1": "drone-pw"})
    process, subscribed = _start_command(broker.url_for("ground"), connection.settings_dict["NAME"])
    try:
        assert subscribed.wait(20), "".join(process.output)  # type: ignore[attr-defined]
        drone = Publisher(broker.url_for("ACME_1"))
        messages = list(drone_messages(time.time() - 30, seconds=30))
        for message in messages:
            drone.publish("ACME_1/telemetry/out", message, qos=1)
        drone.close()
        expected = sum(len(m["objects"]) for m in messages)
        conninfo = _conninfo()
        assert wait_for(lambda: _stored(conninfo, world_tx.drone.pk)[0] >= expected, 20)
        process.send_signal(signal.SIGTERM)
        assert process.wait(20) == 0
        rows, distinct = _stored(conninfo, world_tx.drone.pk)
        assert rows == expected
        assert distinct == expected
    finally:
        if process.poll() is None:
            process.kill()
        broker.stop()


def _ingestor(conninfo: str, broker_url: str, **config: object) -> tuple[Ingestor, CounterSink]:
    counters = CounterSink()
    ingestor = Ingestor(
        IngestConfig(conninfo=conninfo, mqtt_url=broker_url, **config),  # type: ignore[arg-type]
        drones=DroneMap(lambda: load_drone_ids(conninfo)),
        counters=counters,
    )
    ingestor.start()
    assert ingestor.subscriber.subscribed.wait(10)
    return ingestor, counters


def test_bad_messages_are_counted_by_reason_and_nothing_of_them_is_stored(world_tx, tmp_path):
    broker = start_broker(tmp_path, {"ground": "ground-pw"})
    conninfo = _conninfo()
    ingestor, counters = _ingestor(
        conninfo, broker.url_for("ground"), limits=Limits(max_bytes=4096, max_future_s=60)
    )
    ground = Publisher(broker.url_for("ground"))
    now = time.time()
    good = {"ts": now, "objects": [{"name": "Gyros", "ts": now, "fields": {"x": 1.0}}]}
    half_bad = {
        "ts": now,
        "objects": [
            {"name": "Gyros", "ts": now - 1, "fields": {"x": 1.0}},
            {"name": "Accels", "ts": now - 1, "fields": {"x": "1", "y": {"nested": True}}},
        ],
    }
    bad = {
        "not_json": [b"{not json", b"\xff\xfe", b""],
        "bad_value": [
            b'{"ts": 1, "objects": [{"name": "Gyros", "ts": %f, "fields": {"x": NaN}}]}' % now,
            b'{"ts": 1, "objects": [{"name": "Gyros", "ts": %f, "fields": {"x": Infinity}}]}' % now,
            json.dumps(half_bad).encode(),
        ],
        "bad_schema": [
            json.dumps({"ts": now, "objects": {"name": "Gyros"}}).encode(),
            json.dumps(
                {"ts": now, "objects": [{"name": "Gyros", "ts": "soon", "fields": {}}]}
            ).encode(),
            json.dumps(
                {"ts": now, "objects": [{"name": "Gy\tros", "ts": now, "fields": {}}]}
            ).encode(),
        ],
        "ts_window": [
            json.dumps(
                {"ts": now, "objects": [{"name": "Gyros", "ts": now + 3600, "fields": {"x": 1}}]}
            ).encode(),
            json.dumps(
                {"ts": now, "objects": [{"name": "Gyros", "ts": 1000.0, "fields": {"x": 1}}]}
            ).encode(),
        ],
        "oversize": [
            json.dumps(
                {
                    "ts": now,
                    "objects": [{"name": "Gyros", "ts": now, "fields": {"x": 1, "pad": "y" * 200}}]
                    * 30,
                }
            ).encode()
        ],
    }
    try:
        for payloads in bad.values():
            for payload in payloads:
                ground.publish("ACME_1/telemetry/out", payload)
        ground.publish("NOBODY_9/telemetry/out", good)
        ground.publish("ACME_1/telemetry/out", good)
        assert wait_for(lambda: ingestor.stored >= 1, 10)
        for reason, payloads in bad.items():
            assert counters.counts.get(f"dropped.{reason}") == len(payloads), reason
        assert counters.counts["dropped.unknown_drone"] == 1
        assert counters.counts["received"] == sum(map(len, bad.values())) + 2
        assert _stored(conninfo, world_tx.drone.pk) == (1, 1)
    finally:
        ground.close()
        ingestor.stop()
        broker.stop()


def test_a_full_buffer_counts_overflow_instead_of_growing(world_tx, tmp_path):
    broker = start_broker(tmp_path, {"ground": "ground-pw"})
    # No database: the buffer only fills.
    ingestor, counters = _ingestor(
        "host=127.0.0.1 port=1 dbname=none connect_timeout=1",
        broker.url_for("ground"),
        buffer_rows=20,
        put_wait=0.01,
    )
    ingestor.drones.ids = {"ACME_1": world_tx.drone.pk}
    ingestor.drones.loader = lambda: {"ACME_1": world_tx.drone.pk}
    ground = Publisher(broker.url_for("ground"))
    try:
        now = time.time()
        # QoS 0, as drones send telemetry: a QoS 1 delivery is acknowledged only once
        # committed, so the broker would hold those back instead (test_ingest_ack).
        for i in range(30):
            ground.publish(
                "ACME_1/telemetry/out",
                {
                    "ts": now,
                    "objects": [{"name": "Gyros", "ts": now + i * 0.01, "fields": {"x": i}}],
                },
                qos=0,
            )
        counts = counters.counts
        assert wait_for(
            lambda: counts.get("objects_received", 0) + counts.get("overflow", 0) == 30, 10
        )
        assert ingestor.buffer.rows == 20
        assert counters.counts["overflow"] == 10, counters.counts
    finally:
        ground.close()
        ingestor.stop(drain_timeout=0.5)
        broker.stop()


def test_the_ingest_reconnects_after_a_broker_restart_and_keeps_storing(world_tx, tmp_path):
    broker = start_broker(tmp_path, {"ground": "ground-pw"})
    ingestor, counters = _ingestor(_conninfo(), broker.url_for("ground"))
    try:
        now = time.time()

        def send(i: int) -> None:
            ground = Publisher(broker.url_for("ground"))
            ground.publish(
                "ACME_1/telemetry/out",
                {"ts": now, "objects": [{"name": "Gyros", "ts": now + i, "fields": {"x": i}}]},
            )
            ground.close()

        send(0)
        assert wait_for(lambda: ingestor.stored == 1, 10)
        broker.restart(down_for=0.5)
        assert wait_for(lambda: ingestor.subscriber.sessions == 2, 15)
        send(1)
        assert wait_for(lambda: ingestor.stored == 2, 10)
        assert _stored(_conninfo(), world_tx.drone.pk) == (2, 2)
    finally:
        ingestor.stop()
        broker.stop()


def test_a_drone_provisioned_after_the_ingest_started_loses_no_first_sample(world_tx, tmp_path):
    from tests.factories import drone

    broker = start_broker(tmp_path, {"ground": "ground-pw"})
    conninfo = _conninfo()
    ingestor, counters = _ingestor(conninfo, broker.url_for("ground"))
    ground = Publisher(broker.url_for("ground"))
    try:
        time.sleep(0.6)  # past the miss rate limit, as a drone provisioned later would be
        newcomer = drone(world_tx.org, "LATE_1")
        now = time.time()
        message = {"ts": now, "objects": [{"name": "Gyros", "ts": now, "fields": {"x": 1.0}}]}
        ground.publish("LATE_1/telemetry/out", json.dumps(message).encode())
        assert wait_for(lambda: ingestor.stored >= 1, 10)
        assert counters.counts.get("dropped.unknown_drone", 0) == 0
        assert _stored(conninfo, newcomer.pk) == (1, 1)
    finally:
        ground.close()
        ingestor.stop()
        broker.stop()

"""Telemetry ingest and query benchmarks.

    .venv/bin/python -m bench.bench_telemetry

Runs against the test profile's PostgreSQL (`scripts/services.sh start test`) in its own
database `bench_telemetry`, a private Mosquitto with 1 000 drone users, and the real
`manage.py ingest_telemetry --processes 2` (two readers sharing the subscription; set
BENCH_TELEMETRY_INGEST_PROCESSES=1 for the single process `make run` starts). The load
generator is 4 processes, each holding 250 raw MQTT 3.1.1 connections (CONNECT as the drone, then QoS 0 PUBLISH packets written
straight to the socket): paho's per-client threads would cost more CPU than the ingest on
a 2-core machine. A blocking socket write is the broker's back-pressure.

Phases (each capped, ~3 minutes in all):
1. steady: 1 000 drones × 10 Hz, one AttitudeActual per message, for STEADY_S seconds;
   end-to-end lag sampled every second from the newest stored timestamp.
2. max: every drone publishes MAX_MESSAGES messages of 10 objects as fast as the broker
   accepts; stored objects/s from first publish to last row, and the lost count.
3. baselines in the same run: raw COPY of the same rows, and row-by-row INSERT + commit.
4. range query: one day of a 10 Hz object (plus five 1 Hz objects) and one field
   downsampled to 1 000 points, against fetching the raw rows and bucketing in numpy.
"""

from __future__ import annotations

import importlib
import json
import multiprocessing as mp
import os
import socket
import sys
import tempfile
import threading
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import psutil
import psycopg

from bench.common import best_of, percentile, record, test_profile_env
from runtime.mqttwire import connect_packet, publish_packet
from runtime.processes import Supervised, free_port, python_env, wait_for
from workers.mosquitto import GROUND_AND_DRONES_ACL, Broker

DB_NAME = "bench_telemetry"
DRONES = 1000
WORKERS = 4
INGEST_PROCESSES = int(os.environ.get("BENCH_TELEMETRY_INGEST_PROCESSES", 2))
# Lag samples from the first seconds (1 000 CONNECTs, cold caches) are reported apart.
WARMUP_S = 5.0
STEADY_S = float(os.environ.get("BENCH_TELEMETRY_STEADY_S", 60))
STEADY_HZ = 10
MAX_MESSAGES = int(os.environ.get("BENCH_TELEMETRY_MAX_MESSAGES", 40))
OBJECTS_PER_MAX_MESSAGE = 10
MAX_OBJECT_NAMES = [
    "AttitudeActual",
    "Gyros",
    "Accels",
    "BaroAltitude",
    "SystemStats",
    "FlightBatteryState",
    "PositionActual",
    "VelocityActual",
    "GPSPosition",
    "PathDesired",
]


def _conninfo(dbname: str) -> str:
    url = urlsplit(test_profile_env()["DATABASE_URL"])
    return psycopg.conninfo.make_conninfo(
        host=url.hostname,
        port=str(url.port),
        user=url.username,
        password=url.password,
        dbname=dbname,
    )


def drone_id(i: int) -> str:
    return f"BENCH_{i:04d}"


def fresh_database() -> str:
    """Recreate bench_telemetry with the migration's schema and the drones."""
    with psycopg.connect(_conninfo("skyhive"), autocommit=True) as admin:
        admin.execute(f"DROP DATABASE IF EXISTS {DB_NAME} WITH (FORCE)")
        admin.execute(f"CREATE DATABASE {DB_NAME}")
    conninfo = _conninfo(DB_NAME)
    schema = [
        importlib.import_module(f"telemetry.migrations.{name}").SQL
        for name in ("0001_partitioned_samples", "0002_labels_apart_from_numbers")
    ]
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute("CREATE TABLE fleet_drone (id bigserial PRIMARY KEY, drone_id text UNIQUE)")
        with conn.cursor() as cursor:
            cursor.executemany(
                "INSERT INTO fleet_drone (drone_id) VALUES (%s)",
                [(drone_id(i),) for i in range(DRONES)],
            )
        for sql in schema:
            conn.execute(sql)
        # When each row was written, so the max phase's end is read from the rows rather
        # than from how often it is polled (bench database only; both sides write it).
        conn.execute(
            "ALTER TABLE telemetry_sample ADD COLUMN stored_at timestamptz "
            "DEFAULT clock_timestamp()"
        )
        from telemetry import storage

        storage.ensure_partitions_ahead(
            conn, today=datetime.now(UTC).date() - timedelta(days=1), days_ahead=2
        )
    return conninfo


# ---------------------------------------------------------------------------------------
# Raw MQTT 3.1.1 load generator


def _drain(sock: socket.socket) -> None:
    """Read and ignore whatever the broker sends (nothing, for QoS 0 publishers)."""
    sock.setblocking(False)
    try:
        while sock.recv(65536):
            pass
    except (BlockingIOError, OSError):
        pass
    sock.setblocking(True)


def _connect_all(port: int, ids: list[str]) -> list[socket.socket]:
    """One raw MQTT connection per drone, each CONNACKed."""
    sockets = []
    for i in ids:
        sock = socket.create_connection(("127.0.0.1", port))
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.sendall(connect_packet(f"bench-{i}", i, "pw", keepalive=0, clean_session=True))
        ack = sock.recv(4)
        if ack[:2] != b"\x20\x02" or ack[3] != 0:
            raise RuntimeError(f"{i}: CONNACK {ack!r}")
        sockets.append(sock)
    return sockets


def _steady_payload(ts: float) -> bytes:
    """One AttitudeActual, as a drone streams it."""
    fields = {"q1": 1.0, "q2": 0.0, "q3": 0.0, "q4": 0.0, "Roll": 1.5, "Pitch": -0.5, "Yaw": 87.0}
    objects = [{"name": "AttitudeActual", "ts": ts, "fields": fields}]
    return json.dumps({"ts": ts, "objects": objects}).encode()


def _max_payload(seq: int, ts: float) -> bytes:
    """OBJECTS_PER_MAX_MESSAGE objects in one message."""
    fields = {"x": seq * 0.5, "y": 1.0, "z": -9.8, "temperature": 31.5}
    objects = [{"name": name, "ts": ts, "fields": fields} for name in MAX_OBJECT_NAMES]
    return json.dumps({"ts": ts, "objects": objects}).encode()


def _publish_steady(sockets: list[socket.socket], topics: list[str], start_at: float) -> int:
    """Every drone at STEADY_HZ for STEADY_S seconds, on a fixed schedule; objects sent."""
    period = 1.0 / STEADY_HZ
    end = start_at + STEADY_S
    objects = 0
    tick = 0
    while (due := start_at + tick * period) < end:
        delay = due - time.time()
        if delay > 0:
            time.sleep(delay)
        for sock, topic in zip(sockets, topics, strict=True):
            sock.sendall(publish_packet(topic, _steady_payload(time.time())))
            objects += 1
        tick += 1
    return objects


def _publish_max(sockets: list[socket.socket], topics: list[str]) -> int:
    """MAX_MESSAGES messages per drone as fast as the broker takes them; objects sent."""
    base = time.time() - 60
    objects = 0
    for seq in range(MAX_MESSAGES):
        # Every drone sends the same message in a round: encoded once, so the generator's
        # JSON work does not take the ingest's cores (it ran 250 times per round).
        payload = _max_payload(seq, base + seq * 0.001)
        for sock, topic in zip(sockets, topics, strict=True):
            sock.sendall(publish_packet(topic, payload))
            objects += OBJECTS_PER_MAX_MESSAGE
    return objects


def load_worker(port: int, ids: list[str], mode: str, start_at: float, out: mp.Queue) -> None:
    sockets = _connect_all(port, ids)
    topics = [f"{i}/telemetry/out" for i in ids]
    time.sleep(max(0.0, start_at - time.time()))
    if mode == "steady":
        objects = _publish_steady(sockets, topics, start_at)
    else:
        objects = _publish_max(sockets, topics)
    for sock in sockets:
        _drain(sock)
        sock.sendall(b"\xe0\x00")  # DISCONNECT
        sock.close()
    out.put(objects)


def run_load(port: int, mode: str, lead: float = 3.0) -> tuple[list[mp.Process], mp.Queue, float]:
    ctx = mp.get_context("fork")
    out: mp.Queue = ctx.Queue()
    start_at = time.time() + lead
    ids = [drone_id(i) for i in range(DRONES)]
    workers = [
        ctx.Process(target=load_worker, args=(port, ids[w::WORKERS], mode, start_at, out))
        for w in range(WORKERS)
    ]
    for worker in workers:
        worker.start()
    return workers, out, start_at


def collect(workers: list[mp.Process], out: mp.Queue) -> int:
    total = sum(out.get(timeout=STEADY_S + 120) for _ in workers)
    for worker in workers:
        worker.join(10)
    return total


# ---------------------------------------------------------------------------------------


class IngestProcess:
    """`manage.py ingest_telemetry` on the bench database; its memory sampled meanwhile."""

    def __init__(self, conninfo: str, mqtt_url: str, log: Path) -> None:
        argv = [sys.executable, "manage.py", "ingest_telemetry", "--database-url", conninfo,
                "--mqtt-url", mqtt_url, "--no-live", "--processes", str(INGEST_PROCESSES)]  # fmt: skip
        env = python_env(DJANGO_SETTINGS_MODULE="config.settings.test", LOG_LEVEL="INFO")
        self.process = Supervised("ingest", argv, env, log).start()
        # Ready once every reader has subscribed.
        if not wait_for(lambda: self.process.output().count("subscribed") >= INGEST_PROCESSES, 30):
            raise RuntimeError("ingest did not subscribe:\n" + self.process.output())
        self.ps = psutil.Process(self.process.pid)
        self.peak_rss = 0
        self._sampling = True
        threading.Thread(target=self._sample, daemon=True).start()

    def _processes(self) -> list[psutil.Process]:
        """The processes that ingest: the children when the command supervises several."""
        return self.ps.children() or [self.ps]

    def _sample(self) -> None:
        while self._sampling:
            try:
                self.peak_rss = max(self.peak_rss, self.rss())
            except psutil.Error:
                return
            time.sleep(0.2)

    def rss(self) -> int:
        """The largest resident set of one ingest process."""
        return max(p.memory_info().rss for p in self._processes())

    def stop(self) -> None:
        self._sampling = False
        self.process.stop(60)


def stored(conn: psycopg.Connection) -> int:
    return conn.execute("SELECT count(*) FROM telemetry_sample").fetchone()[0]


def last_written(conn: psycopg.Connection) -> float:
    """When the newest row was written (epoch seconds; its commit follows within ms)."""
    return conn.execute(
        "SELECT extract(epoch FROM max(stored_at))::float8 FROM telemetry_sample"
    ).fetchone()[0]


def wait_stored(conn: psycopg.Connection, expected: int, quiet_s: float = 5.0) -> tuple[int, float]:
    """Poll until `expected` rows or no growth for quiet_s; (rows, when the last was written).

    The count runs on one core once a second: a parallel count(*) every 0.1 s took about
    half of one of the two cores from the ingest it was waiting for."""
    conn.execute("SET max_parallel_workers_per_gather = 0")
    last, last_change = -1, time.time()
    while True:
        n = stored(conn)
        if n != last:
            last, last_change = n, time.time()
        if n >= expected or time.time() - last_change > quiet_s:
            return n, last_written(conn) if n else last_change
        time.sleep(1.0)


def phase_steady(conn: psycopg.Connection, port: int) -> dict:
    workers, out, start_at = run_load(port, "steady")
    lags = []
    time.sleep(max(0.0, start_at - time.time()) + 2)
    while time.time() < start_at + STEADY_S - 0.5:
        # Taken before the query: what was stored by then, not how long the query took.
        asked = time.time()
        newest = conn.execute(
            "SELECT extract(epoch FROM max(ts)) FROM telemetry_sample "
            "WHERE ts > now() - interval '30 seconds'"
        ).fetchone()[0]
        if newest is not None:
            lags.append((asked - start_at, asked - float(newest)))
        time.sleep(1.0)
    published = collect(workers, out)
    rows, _ = wait_stored(conn, published)
    every = [lag for _, lag in lags]
    warm = [lag for at, lag in lags if at >= WARMUP_S] or every
    return {
        "published": published,
        "stored": rows,
        "lost": published - rows,
        "rate": rows / STEADY_S,
        "lag_max": max(every),
        "lag_p50": percentile(every, 50),
        "lag_p99": percentile(every, 99),
        "warm_lag_max": max(warm),
        "warm_lag_p50": percentile(warm, 50),
        "warm_lag_p99": percentile(warm, 99),
    }


def phase_max(conn: psycopg.Connection, port: int) -> dict:
    workers, out, start_at = run_load(port, "max")
    published = collect(workers, out)
    rows, last = wait_stored(conn, published)
    return {
        "published": published,
        "stored": rows,
        "lost": published - rows,
        "rate": rows / (last - start_at),
        "seconds": last - start_at,
    }


def _max_rows(n_rows: int):
    from telemetry.storage import Sample

    base = time.time() - 3600
    per_drone = n_rows // (DRONES * OBJECTS_PER_MAX_MESSAGE)
    for seq in range(per_drone):
        for pk in range(1, DRONES + 1):
            ts = base + seq * 0.001
            for name in MAX_OBJECT_NAMES:
                yield Sample(
                    ts, pk, name, {"x": seq * 0.5, "y": 1.0, "z": -9.8, "temperature": 31.5}
                )


def baseline_copy(conn: psycopg.Connection, n_rows: int) -> float:
    """Raw COPY of the same rows in 5 000-row transactions: objects per second."""
    from telemetry import storage

    lines = [s for s in _max_rows(n_rows)]
    start = time.perf_counter()
    for i in range(0, len(lines), 5000):
        with conn.transaction():
            storage.copy_samples(conn, lines[i : i + 5000])
    return len(lines) / (time.perf_counter() - start)


def baseline_insert(conninfo: str, seconds: float = 5.0) -> float:
    """The naive connector: one INSERT and commit per object, objects per second."""
    from telemetry import storage

    with psycopg.connect(conninfo) as conn:
        rows = _max_rows(10**7)
        done = 0
        start = time.perf_counter()
        while time.perf_counter() - start < seconds:
            storage.insert_samples_row_by_row(conn, [next(rows) for _ in range(100)])
            done += 100
        return done / (time.perf_counter() - start)


def load_day(conn: psycopg.Connection, day_start: datetime) -> None:
    from telemetry import storage

    t0 = day_start.timestamp()
    rng = np.random.default_rng(3)
    roll = np.cumsum(rng.normal(0, 0.2, 864_000))
    batch = []
    for i in range(864_000):
        t = t0 + i * 0.1
        batch.append(
            storage.Sample(
                t,
                1,
                "AttitudeActual",
                {
                    "q1": 1.0,
                    "q2": 0.0,
                    "q3": 0.0,
                    "q4": 0.0,
                    "Roll": float(roll[i]),
                    "Pitch": -0.5,
                    "Yaw": 87.0,
                },
            )
        )
        if i % 10 == 0:
            for name in ("BaroAltitude", "Gyros", "Accels", "SystemStats", "FlightBatteryState"):
                batch.append(storage.Sample(t, 1, name, {"x": 1.0, "y": 2.0, "z": 3.0}))
        if len(batch) >= 50_000:
            with conn.transaction():
                storage.copy_samples(conn, batch)
            batch = []
    with conn.transaction():
        storage.copy_samples(conn, batch)
    conn.execute("VACUUM ANALYZE telemetry_sample")


def naive_range(conninfo: str, start: datetime, end: datetime, points: int) -> int:
    with psycopg.connect(conninfo) as conn:
        rows = conn.execute(
            "SELECT extract(epoch FROM ts)::float8, (fields->>'Roll')::float8 FROM telemetry_sample "
            "WHERE drone_id = 1 AND object = 'AttitudeActual' AND ts >= %s AND ts < %s",
            (start, end),
        ).fetchall()
    data = np.array(rows)
    width = (end - start).total_seconds() / points
    index = ((data[:, 0] - start.timestamp()) // width).astype(int)
    order = np.argsort(index, kind="stable")
    index, values = index[order], data[order, 1]
    bounds = np.flatnonzero(np.diff(index)) + 1
    np.minimum.reduceat(values, np.r_[0, bounds])
    np.maximum.reduceat(values, np.r_[0, bounds])
    return len(np.add.reduceat(values, np.r_[0, bounds]))


def bench_range(conninfo: str) -> None:
    os.environ["TEST_WORKER_DB_NAME"] = DB_NAME
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
    import django

    django.setup()
    from telemetry import queries

    day_start = datetime.combine(
        datetime.now(UTC).date() - timedelta(days=1), datetime.min.time(), UTC
    )
    day_end = day_start + timedelta(days=1)
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute("TRUNCATE telemetry_sample")
        load_day(conn, day_start)
    result = queries.query_range(1, "AttitudeActual", ["Roll"], day_start, day_end, 1000)
    assert len(result.t) == 1000 and sum(result.count) == 864_000, (
        len(result.t),
        sum(result.count),
    )
    ours = best_of(
        lambda: queries.query_range(1, "AttitudeActual", ["Roll"], day_start, day_end, 1000),
        repeat=5,
    )
    naive = best_of(lambda: naive_range(conninfo, day_start, day_end, 1000), repeat=3)
    record(
        "telemetry.range_query_1day",
        value=ours * 1000,
        unit="ms",
        baseline_name="fetch the day's raw rows and bucket them in numpy",
        baseline_value=naive * 1000,
        higher_is_better=False,
        goal="well under 1 s for 864 000 samples → 1 000 min/max/avg buckets",
        rows=864_000,
        other_rows_in_table=432_000,
        points=1000,
        load_average=os.getloadavg(),
    )


def _ingest_phases(conninfo: str) -> tuple[dict, dict, int, int]:
    """The steady and max phases through a private broker and the real ingest:
    (steady, max, idle RSS, peak RSS)."""
    directory = Path(tempfile.mkdtemp(prefix="bench-telemetry-"))
    users = {"ground": "ground-pw", **{drone_id(i): "pw" for i in range(DRONES)}}
    broker = Broker(
        directory,
        free_port(),
        users,
        GROUND_AND_DRONES_ACL,
        "max_connections -1\nmax_queued_messages 100000\n",
    ).start()
    ingest = IngestProcess(conninfo, broker.url_for("ground"), directory / "ingest.log")
    try:
        time.sleep(1)
        idle_rss = ingest.rss()
        with psycopg.connect(conninfo, autocommit=True) as conn:
            steady = phase_steady(conn, broker.port)
            print("steady:", steady, flush=True)
            conn.execute("TRUNCATE telemetry_sample")
            peak = phase_max(conn, broker.port)
            print("max:", peak, flush=True)
        return steady, peak, idle_rss, ingest.peak_rss
    finally:
        ingest.stop()
        broker.stop()


def _record_ingest(steady: dict, peak: dict, copy_rate: float, insert_rate: float) -> None:
    load = (
        f"{WORKERS} processes × {DRONES // WORKERS} raw MQTT 3.1.1 connections, one per "
        "drone with its own credentials, QoS 0 PUBLISH written to blocking sockets"
    )
    record(
        "telemetry.ingest_msgs_per_s",
        value=peak["rate"],
        unit="objects/s",
        baseline_name="raw COPY of the same rows (5 000-row transactions)",
        baseline_value=copy_rate,
        higher_is_better=True,
        goal="≥ 50 % of raw COPY with no loss",
        lost=peak["lost"],
        published=peak["published"],
        stored=peak["stored"],
        seconds=peak["seconds"],
        connections=DRONES,
        objects_per_message=OBJECTS_PER_MAX_MESSAGE,
        ingest_processes=INGEST_PROCESSES,
        load_average=os.getloadavg(),
        load_generator=load,
    )
    record(
        "telemetry.ingest_vs_insert",
        value=steady["rate"],
        unit="objects/s",
        baseline_name="row-by-row INSERT with a commit per object (the naive connector)",
        baseline_value=insert_rate,
        higher_is_better=True,
        goal=f"10 000 objects/s (1 000 drones × 10 Hz) held for {STEADY_S:.0f} s, "
        "lag under 1 s, nothing lost",
        lost=steady["lost"],
        published=steady["published"],
        lag_max_s=round(steady["lag_max"], 3),
        lag_p50_s=round(steady["lag_p50"], 3),
        lag_p99_s=round(steady["lag_p99"], 3),
        after_warmup={
            "seconds": WARMUP_S,
            "lag_max_s": round(steady["warm_lag_max"], 3),
            "lag_p50_s": round(steady["warm_lag_p50"], 3),
            "lag_p99_s": round(steady["warm_lag_p99"], 3),
        },
        lag_measure="newest stored sample time vs wall clock, sampled every second",
        load_average=os.getloadavg(),
        seconds=STEADY_S,
        load_generator=load,
        ingest_processes=INGEST_PROCESSES,
    )


def _record_memory(idle_rss: int, peak_rss: int) -> None:
    record(
        "telemetry.ingest_peak_rss",
        value=peak_rss / 2**20,
        unit="MiB",
        baseline_name="the same ingest process idle, subscribed",
        baseline_value=idle_rss / 2**20,
        higher_is_better=False,
        goal="bounded by the buffer (TELEMETRY_BUFFER_ROWS), whatever the load",
        processes=INGEST_PROCESSES,
        per="largest single ingest process",
        phases="steady 10 000 objects/s, then max rate",
    )


def main() -> None:
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
    conninfo = fresh_database()
    steady, peak, idle_rss, peak_rss = _ingest_phases(conninfo)
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute("TRUNCATE telemetry_sample")
        copy_rate = baseline_copy(conn, peak["published"])
        conn.execute("TRUNCATE telemetry_sample")
    insert_rate = baseline_insert(conninfo)
    _record_ingest(steady, peak, copy_rate, insert_rate)
    _record_memory(idle_rss, peak_rss)
    bench_range(conninfo)


if __name__ == "__main__":
    main()

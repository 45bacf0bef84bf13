"""The broker-to-database connector: MQTT telemetry in, COPY batches out, nothing lost.

Three parts, each usable alone: `parse_message` (bytes → validated objects, or `Rejected`
with a counter name), `SampleBuffer` (bounded, in memory, in rows) and `Ingestor` (an MQTT
reader feeding the buffer — see mqtt_reader for why not paho — or, on RabbitMQ, an AMQP
consumer of the shared queue `skyhive.ingest`, and a writer thread that COPYs it,
retrying through a database restart). No Django here: the management command wires settings, the drone map
and the live publisher in.

A message is acknowledged to the broker (an AMQP ack; the PUBACK of a QoS 1 delivery)
only once its rows are committed, or once it is refused for good: an ingest killed with
messages buffered gets them again from RabbitMQ's queue.
"""

from __future__ import annotations

import json
import logging
import math
import os
import socket
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import date, timedelta
from typing import TYPE_CHECKING

import psycopg

from onboard.protocol import OBJECT_NAME_RE, ProtocolError, parse_telemetry, text_problem
from runtime.retry import Backoff

from . import storage

if TYPE_CHECKING:
    from workers.broker import Consumer

log = logging.getLogger(__name__)

# (topic, payload, settle): one message as the broker readers hand it over.
Delivery = tuple[str, bytes, Callable[[], None] | None]

SHARE_GROUP = "ingest"
EPOCH = date(1970, 1, 1)
MAX_FIELDS = 64
MAX_ARRAY = 64
MAX_STRING = 256


class Rejected(ValueError):
    """A message dropped whole; `reason` is the counter it is counted under."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


@dataclass(frozen=True)
class Limits:
    max_bytes: int = 256 * 1024
    max_past_s: float = 7 * 86400
    max_future_s: float = 300


def _refuse_constant(name: str) -> float:
    # Python's json accepts NaN and Infinity, which are not JSON; PostgreSQL's jsonb refuses them.
    raise Rejected("bad_value", f"{name} is not a JSON number")


def _check_value(value: object, where: Callable[[], str]) -> None:
    """Raise Rejected unless a storable field value; `where` names it, built only on error."""
    kind = type(value)
    if kind is float:
        if not math.isfinite(value):  # type: ignore[arg-type]
            raise Rejected("bad_value", f"{where()}: not a finite number")
        return
    if kind is int:
        # Beyond this, PostgreSQL's float8 cast of the stored number would fail the query.
        if abs(value) >= 2**63:  # type: ignore[arg-type]
            raise Rejected("bad_value", f"{where()}: integer out of range")
        return
    if kind is bool:
        return
    if kind is str:
        if len(value) > MAX_STRING:  # type: ignore[arg-type]
            raise Rejected("bad_value", f"{where()}: string longer than {MAX_STRING}")
        if "\x00" in value or not value.isascii():  # type: ignore[operator,union-attr]
            problem = text_problem(value)  # type: ignore[arg-type]
            if problem is not None:
                raise Rejected("bad_text", f"{where()}: {problem}")
        return
    if kind is list and len(value) <= MAX_ARRAY:  # type: ignore[arg-type]
        for i, item in enumerate(value):  # type: ignore[arg-type]
            if type(item) is list:
                raise Rejected("bad_value", f"{where()}[{i}]: nested list")
            _check_value(item, lambda i=i: f"{where()}[{i}]")
        return
    raise Rejected("bad_value", f"{where()}: {kind.__name__} is not a field value")


# The protocol's storage faults under this process's long-standing counter names.
_PROTOCOL_REASONS = {
    "bad_text": "bad_text",
    "not_finite": "bad_value",
    "too_long": "bad_value",
    "bad_timestamp": "ts_window",
}

_VALID_NAMES: set[str] = set()
# One decoder for every message (json.loads with options builds a new one per call).
_DECODER = json.JSONDecoder(parse_constant=_refuse_constant)
isfinite = math.isfinite


def _valid_name(name: str) -> bool:
    """OBJECT_NAME_RE, remembered: the same few hundred names arrive thousands of times."""
    if name in _VALID_NAMES:
        return True
    if not OBJECT_NAME_RE.match(name):
        return False
    if len(_VALID_NAMES) < 10_000:
        _VALID_NAMES.add(name)
    return True


def parse_message(payload: bytes, *, now: float, limits: Limits) -> list[tuple[str, float, dict]]:
    """Validate one telemetry message whole; its objects as (name, ts, fields).

    Any bad part rejects the whole message, so nothing partial is ever stored.
    """
    if len(payload) > limits.max_bytes:
        raise Rejected("oversize", f"{len(payload)} bytes > {limits.max_bytes}")
    try:
        data = _DECODER.decode(payload.decode("utf-8"))
    except Rejected:
        raise
    except (ValueError, UnicodeDecodeError) as exc:
        raise Rejected("not_json", str(exc)) from None
    try:
        message = parse_telemetry(data)
    except ProtocolError as exc:
        raise Rejected(_PROTOCOL_REASONS.get(exc.reason, "bad_schema"), str(exc)) from None
    lo, hi = now - limits.max_past_s, now + limits.max_future_s
    objects = []
    for i, obj in enumerate(message.objects):
        if not _valid_name(obj.name):
            raise Rejected("bad_schema", f"objects[{i}].name {obj.name!r} is not an object name")
        if not lo <= obj.ts <= hi:
            raise Rejected("ts_window", f"objects[{i}].ts {obj.ts} outside [{lo:.0f}, {hi:.0f}]")
        if len(obj.fields) > MAX_FIELDS:
            raise Rejected("bad_value", f"objects[{i}] has more than {MAX_FIELDS} fields")
        for name, value in obj.fields.items():
            if name not in _VALID_NAMES and not _valid_name(name):
                raise Rejected("bad_schema", f"objects[{i}].fields: bad field name {name!r}")
            # Finite floats are nearly every value: checked here, without a call.
            if type(value) is float and isfinite(value):
                continue
            _check_value(value, lambda i=i, name=name: f"objects[{i}].fields.{name}")
        objects.append((obj.name, obj.ts, obj.fields))
    return objects


# ---------------------------------------------------------------------------------------


@dataclass
class Chunk:
    """One accepted message, already in COPY text form."""

    received: float  # monotonic
    rows: int
    text: str
    days: frozenset[int]  # UTC days since the epoch, for the partitions they need
    drone: str = ""  # who sent it, to count a refusal against
    settle: Callable[[], None] | None = None  # acknowledges it to the broker


# A pause this long in the input ends a batch: at the end of a burst, its last rows are
# written at once rather than after the flush interval. Longer than the reader's gap
# between two full reads on a busy core, so a steady stream still fills whole batches.
QUIET_S = 0.05


class SampleBuffer:
    """Accepted messages not yet committed, bounded in rows.

    Rows taken by the writer still count against the bound until `release`, so a batch
    being retried through a database outage is part of what the bound limits.
    """

    def __init__(self, max_rows: int) -> None:
        self.max_rows = max_rows
        self.queued = 0
        self.held = 0
        self._chunks: deque[Chunk] = deque()
        lock = threading.Lock()
        # Two conditions on one lock, and a wake-up only when the waiter can go on: a
        # notify per message would hand the GIL to the writer 10 000 times a second just
        # for it to find too few rows and sleep again, and the MQTT reader, waiting for
        # the GIL back behind a thread the busy OS has not scheduled yet, falls behind.
        self._rows_ready = threading.Condition(lock)
        self._room_made = threading.Condition(lock)
        self._wanted: int | None = None  # rows the waiting writer asked for
        self._room_waiters = 0

    @property
    def rows(self) -> int:
        return self.queued + self.held

    def put(self, chunk: Chunk, wait: float) -> bool:
        """Add a chunk, waiting up to `wait` s for room (back-pressure on the MQTT reader)."""
        return self.put_many([chunk], wait) == 1

    def put_many(self, chunks: Sequence[Chunk], wait: float) -> int:
        """Add chunks in order, waiting up to `wait` s in all for room; how many went in
        (the first ones: a chunk never overtakes an earlier one of the same read)."""
        added = 0
        deadline = time.monotonic() + wait
        with self._room_made:
            for chunk in chunks:
                if self.rows + chunk.rows > self.max_rows and not self._wait_for_room(
                    chunk.rows, deadline - time.monotonic()
                ):
                    break
                self._chunks.append(chunk)
                self.queued += chunk.rows
                added += 1
            if added and self._wanted is not None and self.queued >= self._wanted:
                self._rows_ready.notify()
        return added

    def _wait_for_room(self, rows: int, wait: float) -> bool:
        deadline = time.monotonic() + wait
        self._room_waiters += 1
        try:
            while self.rows + rows > self.max_rows:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._room_made.wait(remaining)
            return True
        finally:
            self._room_waiters -= 1

    def take(
        self, max_rows: int, wait: float, min_rows: int, quiet: float = QUIET_S
    ) -> list[Chunk]:
        """Up to max_rows worth of chunks, once min_rows are queued, or rows are queued and
        none came for `quiet` s (the input paused: nothing is gained by waiting for more),
        or `wait` s passed."""
        with self._rows_ready:
            deadline = time.monotonic() + wait
            self._wanted = min_rows
            try:
                seen = 0
                while self.queued < min_rows:
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or seen == self.queued > 0:
                        break
                    seen = self.queued
                    self._rows_ready.wait(min(remaining, quiet))
            finally:
                self._wanted = None
            out: list[Chunk] = []
            taken = 0
            while self._chunks and (not out or taken + self._chunks[0].rows <= max_rows):
                chunk = self._chunks.popleft()
                out.append(chunk)
                taken += chunk.rows
            self.queued -= taken
            self.held += taken
            return out

    def release(self, rows: int) -> None:
        """Rows taken earlier are committed (or given up): make room for new ones."""
        with self._room_made:
            self.held -= rows
            if self._room_waiters:
                self._room_made.notify_all()


def _settle(chunks: list[Chunk]) -> None:
    for chunk in chunks:
        if chunk.settle is not None:
            chunk.settle()


# ---------------------------------------------------------------------------------------


class DroneMap:
    """drone_id → primary key, cached; refreshed periodically and at once on a miss."""

    def __init__(
        self, loader: Callable[[], dict[str, int]], every: float = 30.0, after_miss: float = 0.5
    ) -> None:
        self.loader = loader
        self.every = every
        self.after_miss = after_miss
        self.ids: dict[str, int] = {}
        self._loaded_at = -math.inf
        self._missed = False

    def get(self, drone_id: str) -> int | None:
        pk = self.ids.get(drone_id)
        if pk is None:
            # A drone provisioned since the last load: look again now rather than drop its
            # first samples. Rate-limited, so a flood from a bogus topic costs one query
            # per `after_miss` seconds.
            self._missed = True
            if time.monotonic() - self._loaded_at >= self.after_miss:
                self.refresh()
                pk = self.ids.get(drone_id)
        return pk

    def maybe_refresh(self) -> None:
        age = time.monotonic() - self._loaded_at
        if age >= self.every or (self._missed and age >= self.after_miss):
            self.refresh()

    def refresh(self) -> None:
        try:
            self.ids = self.loader()
            self._missed = False
        except psycopg.Error as exc:
            log.warning("drone map not refreshed: %s", exc)
        self._loaded_at = time.monotonic()


def load_drone_ids(conninfo: str) -> dict[str, int]:
    with psycopg.connect(conninfo, connect_timeout=3) as conn:
        return dict(conn.execute("SELECT drone_id, id FROM fleet_drone").fetchall())


class CounterSink:
    """What the ingestor counts into; `workers.counters.Counters` fits, so does this."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self.gauges: dict[str, float] = {}
        self.refusals: dict[tuple[str, str], int] = {}
        self._lock = threading.Lock()

    def incr(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self.counts[name] = self.counts.get(name, 0) + amount

    def gauge(self, name: str, value: float) -> None:
        self.gauges[name] = value

    def refused(self, drone_id: str, reason: str, amount: int = 1) -> None:
        with self._lock:
            key = (drone_id, reason)
            self.refusals[key] = self.refusals.get(key, 0) + amount

    def maybe_flush(self) -> None:
        return

    def flush(self) -> None:
        return


LivePublisher = Callable[[dict[int, dict[str, tuple[float, dict]]]], None]


@dataclass
class IngestConfig:
    conninfo: str
    mqtt_url: str
    flush_rows: int = 5000
    flush_interval: float = 0.2
    buffer_rows: int = 500_000
    limits: Limits = field(default_factory=Limits)
    live_hz: float = 5.0
    client_id: str = ""
    put_wait: float = 0.5
    # RabbitMQ: read the shared queue skyhive.ingest from these nodes (in try order)
    # instead of an MQTT shared subscription. A large window keeps ~20 000 messages/s
    # flowing on one core; acknowledgements go out in batches once buffered.
    amqp_urls: list[str] = field(default_factory=list)
    amqp_prefetch: int = 5000


class Ingestor:
    """Subscribe, validate, buffer and COPY; `start()`, then `stop()` drains the buffer."""

    def __init__(
        self,
        config: IngestConfig,
        *,
        drones: DroneMap,
        counters: object,
        live: LivePublisher | None = None,
    ) -> None:
        self.config = config
        self.drones = drones
        self.counters = counters
        self.live = live
        self.buffer = SampleBuffer(config.buffer_rows)
        self._conn: psycopg.Connection | None = None
        self._known_days: set[date] = set()
        self._stop_writing = threading.Event()
        self._abandon = threading.Event()
        self._latest: dict[int, dict[str, tuple[float, dict]]] = {}
        self._latest_lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        self._stored_window: deque[tuple[float, int]] = deque()
        self._landed: list[Chunk] = []
        self._refusal = ""  # the database's last word on a refused message, for the log
        self.stored = 0
        self.subscriber = self._make_subscriber()

    # -- MQTT side -------------------------------------------------------------------------

    def _make_subscriber(self) -> Consumer:
        from workers.broker import competing_consumer

        return competing_consumer(
            SHARE_GROUP,
            ["telemetry"],
            self.handle,
            client_id=self.config.client_id or f"ingest-{socket.gethostname()}-{os.getpid()}",
            amqp_urls=self.config.amqp_urls,
            mqtt_url=self.config.mqtt_url,
            prefetch=self.config.amqp_prefetch,
            counters=self.counters,
            manual_ack=True,
            on_messages=self.handle_many,
        )

    def handle(self, topic: str, payload: bytes, settle: Callable[[], None] | None = None) -> bool:
        """One message from the broker: validate, buffer; False if it was dropped. It is
        settled with the broker once committed (or at once, when dropped)."""
        return self.handle_many([(topic, payload, settle)]) == 1

    def handle_many(self, deliveries: Sequence[Delivery]) -> int:
        """Messages read together from the broker, each validated and refused on its own;
        how many were kept. Counters, the buffer and the live values are each touched once
        per batch: at 10 000 messages a second, per-message locking was a large part of
        the reader's time."""
        tally: Counter[str] = Counter(received=len(deliveries))
        now, wall = time.monotonic(), time.time()
        chunks: list[Chunk] = []
        live: list[tuple[int, list[tuple[str, float, dict]]]] = []
        empty = 0
        for topic, payload, settle in deliveries:
            try:
                drone_pk, objects = self._validate(topic, payload, wall)
            except Rejected as exc:
                tally[f"dropped.{exc.reason}"] += 1
                if settle is not None:
                    settle()
                continue
            if not objects:
                empty += 1
                if settle is not None:
                    settle()  # nothing to store
                continue
            chunks.append(self._chunk(topic, drone_pk, objects, now, settle))
            live.append((drone_pk, objects))
        kept = self.buffer.put_many(chunks, self.config.put_wait)
        for chunk in chunks[kept:]:
            tally["overflow"] += 1
            tally["overflow_objects"] += chunk.rows
            if chunk.settle is not None:
                chunk.settle()
        tally["objects_received"] = sum(chunk.rows for chunk in chunks[:kept])
        for name, amount in tally.items():
            if amount:
                self.counters.incr(name, amount)
        if self.live is not None and kept:
            self._remember_latest(live[:kept])
        return kept + empty

    def _validate(
        self, topic: str, payload: bytes, wall: float
    ) -> tuple[int, list[tuple[str, float, dict]]]:
        """(drone pk, objects) of one message; Rejected (reason = counter) if dropped."""
        parts = topic.split("/")
        if len(parts) != 3 or parts[1:] != ["telemetry", "out"]:
            raise Rejected("bad_topic", topic)
        drone_pk = self.drones.get(parts[0])
        if drone_pk is None:
            raise Rejected("unknown_drone", parts[0])
        try:
            return drone_pk, parse_message(payload, now=wall, limits=self.config.limits)
        except Rejected as exc:
            self.counters.refused(parts[0], f"telemetry.{exc.reason}")
            log.debug("dropped telemetry from %s: %s", parts[0], exc)
            raise

    @staticmethod
    def _chunk(
        topic: str,
        drone_pk: int,
        objects: list[tuple[str, float, dict]],
        now: float,
        settle: Callable[[], None] | None,
    ) -> Chunk:
        return Chunk(
            received=now,
            rows=len(objects),
            text="".join(storage.copy_line(ts, drone_pk, name, f) for name, ts, f in objects),
            days=frozenset(int(ts // 86400) for _, ts, _ in objects),
            drone=topic.split("/", 1)[0],
            settle=settle,
        )

    def _remember_latest(self, batch: list[tuple[int, list[tuple[str, float, dict]]]]) -> None:
        with self._latest_lock:
            for drone_pk, objects in batch:
                latest = self._latest.setdefault(drone_pk, {})
                for name, ts, fields in objects:
                    previous = latest.get(name)
                    if previous is None or previous[0] <= ts:
                        latest[name] = (ts, fields)

    # -- database side -----------------------------------------------------------------------

    def _connection(self) -> psycopg.Connection:
        if self._conn is None or self._conn.closed:
            self._conn = psycopg.connect(self.config.conninfo, autocommit=True, connect_timeout=3)
            self._known_days.clear()
        return self._conn

    def _drop_connection(self) -> None:
        if self._conn is not None:
            try:
                self._conn.close()
            except psycopg.Error:
                pass
        self._conn = None

    def _ensure_days(self, conn: psycopg.Connection, epoch_days: set[int]) -> None:
        for day in {EPOCH + timedelta(days=d) for d in epoch_days} - self._known_days:
            try:
                storage.ensure_partition(conn, storage.SAMPLE_TABLE, day)
            except psycopg.errors.Error as exc:
                if conn.closed or conn.broken:
                    raise
                # The default partition still takes the rows; the beat task retries.
                log.warning("partition for %s not created: %s", day, exc)
            self._known_days.add(day)

    def write(self, chunks: list[Chunk], *, idempotent: bool) -> None:
        """Store chunks in one transaction; raises psycopg errors for the caller to retry."""
        conn = self._connection()
        self._ensure_days(conn, set().union(*(c.days for c in chunks)))
        text = "".join(c.text for c in chunks)
        with conn.transaction(), conn.cursor() as cursor:
            storage.copy_rows(cursor, text, idempotent=idempotent)

    def _flush_once(self, pending: list[Chunk], retrying: bool) -> list[Chunk]:
        """Store what the database takes; the chunks it refuses, for the caller to count."""
        try:
            self.write(pending, idempotent=retrying)
        except psycopg.errors.UniqueViolation:
            # A sample already stored (a QoS 1 redelivery): keep the rest, skip the copies.
            return self._flush_once(pending, True)
        except (psycopg.OperationalError, psycopg.InterfaceError):
            raise
        except (psycopg.Error, UnicodeError) as exc:
            # A row validation missed: halve the batch until only the messages the database
            # refuses are left, so no other drone's rows go with them.
            if self._conn is not None and self._conn.broken:
                raise psycopg.OperationalError(str(exc)) from exc
            if len(pending) == 1:
                log.debug("telemetry from %s refused by the database: %s", pending[0].drone, exc)
                self._refusal = str(exc)
                return pending
            half = len(pending) // 2
            return self._flush_once(pending[:half], retrying) + self._flush_once(
                pending[half:], retrying
            )
        self._record_stored(pending)
        return []

    def _count_refused(self, refused: list[Chunk]) -> None:
        for chunk in refused:
            self.counters.incr("dropped.db_rejected", chunk.rows)
            self.counters.refused(chunk.drone, "telemetry.db_rejected", chunk.rows)
        _settle(refused)
        if refused:
            drones = ", ".join(sorted({c.drone for c in refused}))
            log.error(
                "%d telemetry messages refused by the database (from %s): %s",
                len(refused),
                drones,
                self._refusal,
            )

    def _writer(self) -> None:
        pending: list[Chunk] = []
        retrying = False
        backoff = Backoff(0.1, 2.0)
        while True:
            if not pending:
                if self._stop_writing.is_set() and self.buffer.rows == 0:
                    break
                pending = self.buffer.take(
                    max_rows=self.config.flush_rows * 4,
                    wait=self.config.flush_interval,
                    min_rows=self.config.flush_rows,
                )
            self.drones.maybe_refresh()
            if pending:
                self._landed = []
                try:
                    self._count_refused(self._flush_once(pending, retrying))
                except (psycopg.OperationalError, psycopg.InterfaceError) as exc:
                    # The database is away: keep the batch, retry it idempotently, since a
                    # connection lost around COMMIT leaves us not knowing if it landed.
                    # Halves already committed while splitting it are done with.
                    pending = self._without_landed(pending)
                    self.counters.incr("db_errors")
                    wait = backoff.failed()
                    log.warning("telemetry write failed, retrying in %.1f s: %s", wait, exc)
                    self._drop_connection()
                    retrying = True
                    if self._abandon.wait(wait):
                        rows = sum(c.rows for c in pending) + self.buffer.queued
                        self.counters.incr("lost_at_shutdown", rows)
                        log.error("stopped with %d rows never written", rows)
                        return
                    continue
                self.buffer.release(sum(c.rows for c in pending))
                pending = []
                retrying = False
                backoff.reset()
            self._report()

    def _without_landed(self, pending: list[Chunk]) -> list[Chunk]:
        landed = {id(c) for c in self._landed}
        self.buffer.release(sum(c.rows for c in self._landed))
        return [c for c in pending if id(c) not in landed]

    def _record_stored(self, chunks: list[Chunk]) -> None:
        _settle(chunks)  # committed: the broker may forget them
        self._landed.extend(chunks)
        rows = sum(c.rows for c in chunks)
        now = time.monotonic()
        self.stored += rows
        self.counters.incr("stored", rows)
        self.counters.gauge("lag_s", round(now - min(c.received for c in chunks), 4))
        self._stored_window.append((now, rows))

    def _report(self) -> None:
        now = time.monotonic()
        while self._stored_window and self._stored_window[0][0] < now - 5:
            self._stored_window.popleft()
        rate = sum(rows for _, rows in self._stored_window) / 5
        self.counters.gauge("rate_objects_per_s", round(rate, 1))
        self.counters.gauge("buffer_rows", self.buffer.rows)
        self.counters.gauge("alive_at", time.time())
        self.counters.maybe_flush()

    # -- live values -----------------------------------------------------------------------

    def _publisher(self) -> None:
        period = 1.0 / self.config.live_hz
        while not self._stop_writing.wait(period):
            with self._latest_lock:
                latest, self._latest = self._latest, {}
            if latest and self.live is not None:
                try:
                    self.live(latest)
                except Exception:  # noqa: BLE001 - live view is best effort, storage is not
                    log.exception("live telemetry push failed")

    # -- life cycle --------------------------------------------------------------------------

    def start(self) -> None:
        self.drones.refresh()
        self._threads = [threading.Thread(target=self._writer, name="ingest-writer", daemon=True)]
        if self.live is not None:
            self._threads.append(
                threading.Thread(target=self._publisher, name="ingest-live", daemon=True)
            )
        for thread in self._threads:
            thread.start()
        self.subscriber.start()

    def stop(self, drain_timeout: float = 30.0) -> bool:
        """Stop reading, then write what is buffered; True if everything was written."""
        self.subscriber.stop()
        self._stop_writing.set()
        deadline = time.monotonic() + drain_timeout
        for thread in self._threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        drained = not any(t.is_alive() for t in self._threads)
        if not drained:
            self._abandon.set()
            for thread in self._threads:
                thread.join(5)
        self.counters.flush()
        self._drop_connection()
        return drained

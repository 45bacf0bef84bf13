"""Process counters (received, dropped, …) shared through Redis for /health and the admin.

Long-running processes count in memory and flush every second, so the hot path never
waits on Redis. Each flush adds to two places:

- the totals of every process of that name (`skyhive:counters:<process>`), which /health
  and the ingest status have always read;
- the instance's own hash (`skyhive:instance:<process>:<host>:<pid>`), with who it is,
  when it started and last reported, and its own counters. A separate key with a short
  TTL (`skyhive:alive:…`) is the instance heartbeat: while it exists the instance is
  alive; once it expires the instance is gone, and its hash stays a while so the
  operations page can say so.

Every flush renews the heartbeat, even with nothing counted, so an idle but running
process stays alive; processes that count nothing can run `Heartbeat` instead.

Messages refused from a drone are also counted per drone and reason
(`skyhive:refusals`, read by `refusals`), so an operator can see which drone misbehaves.
The drone ids kept are capped (REFUSAL_DRONES): past the cap, a new id is counted under
`OTHER_DRONES`, so a flood of made-up ids cannot grow Redis without bound.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass

import redis
from django.conf import settings

KEY_PREFIX = "skyhive:counters:"
INSTANCE_PREFIX = "skyhive:instance:"
ALIVE_PREFIX = "skyhive:alive:"

# How long a gone instance stays listed before Redis forgets it.
GONE_RETAIN_S = 3600

# Fields of an instance hash that describe it rather than count something.
IDENTITY_FIELDS = ("process", "instance", "host", "pid", "started", "last_report", "ttl")

REFUSALS_KEY = "skyhive:refusals"
REFUSAL_DRONES_KEY = "skyhive:refusals:drones"
OTHER_DRONES = "*"
# Adds per-drone refusals, keeping at most ARGV[1] distinct drone ids; ARGV then holds
# (drone, reason, amount) triples and last the name of the overflow bucket. One script,
# so two processes cannot both pass the cap.
_ADD_REFUSALS = """
local cap = tonumber(ARGV[1])
for i = 2, #ARGV - 1, 3 do
  local drone = ARGV[i]
  if redis.call('SISMEMBER', KEYS[2], drone) == 0 then
    if redis.call('SCARD', KEYS[2]) < cap then
      redis.call('SADD', KEYS[2], drone)
    else
      drone = ARGV[#ARGV]
    end
  end
  redis.call('HINCRBY', KEYS[1], drone .. '|' .. ARGV[i + 1], ARGV[i + 2])
end
"""

log = logging.getLogger(__name__)


def _client() -> redis.Redis:
    return redis.Redis.from_url(settings.REDIS_URL, socket_timeout=1, decode_responses=True)


def default_instance() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


class Counters:
    """In-memory counters for one process, flushed to its name's totals and its own hash."""

    def __init__(
        self,
        process: str,
        flush_every: float = 1.0,
        *,
        instance: str | None = None,
        instance_ttl: float | None = None,
    ):
        self.process = process
        self.flush_every = flush_every
        self.instance = instance or default_instance()
        self.instance_ttl = float(
            instance_ttl if instance_ttl is not None else settings.INSTANCE_TTL_S
        )
        self.started = time.time()
        self._counts: Counter[str] = Counter()
        self._gauges: dict[str, float] = {}
        self._refusals: Counter[tuple[str, str]] = Counter()
        self._lock = threading.Lock()
        self._last_flush = 0.0

    @property
    def instance_key(self) -> str:
        return f"{INSTANCE_PREFIX}{self.process}:{self.instance}"

    @property
    def identity(self) -> str:
        """`<process>:<instance>`: names this process's heartbeat (see `is_alive`)."""
        return f"{self.process}:{self.instance}"

    @property
    def alive_key(self) -> str:
        return ALIVE_PREFIX + self.identity

    def incr(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self._counts[name] += amount

    def gauge(self, name: str, value: float) -> None:
        with self._lock:
            self._gauges[name] = value

    def get(self, name: str) -> int:
        with self._lock:
            return self._counts[name]

    def refused(self, drone_id: str, reason: str, amount: int = 1) -> None:
        """Count a refused message against its drone (`reason` like `heartbeats.bad_text`)."""
        with self._lock:
            refusals = self._refusals
            if (drone_id, reason) not in refusals and len(refusals) >= settings.REFUSAL_DRONES:
                drone_id = OTHER_DRONES  # held in memory until the next flush: bounded too
            refusals[(drone_id, reason)] += amount

    def maybe_flush(self) -> None:
        if time.monotonic() - self._last_flush >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        with self._lock:
            counts = dict(self._counts)
            self._counts.clear()
            gauges = dict(self._gauges)
            refusals = dict(self._refusals)
            self._refusals.clear()
        self._last_flush = time.monotonic()
        now = time.time()
        try:
            pipe = _client().pipeline(transaction=False)
            if counts or gauges:
                key = KEY_PREFIX + self.process
                for name, amount in counts.items():
                    pipe.hincrby(key, name, amount)
                for name, value in gauges.items():
                    pipe.hset(key, name, value)
                pipe.hset(key, "updated_at", now)
            self._write_instance(pipe, counts, gauges, now)
            _add_refusals(pipe, refusals)
            pipe.execute()
        except redis.RedisError:
            # Keep the counts for the next flush rather than losing them.
            with self._lock:
                self._counts.update(counts)
                self._refusals.update(refusals)

    def _write_instance(
        self,
        pipe: redis.client.Pipeline,
        counts: dict[str, int],
        gauges: dict[str, float],
        now: float,
    ) -> None:
        key = self.instance_key
        for name, amount in counts.items():
            pipe.hincrby(key, name, amount)
        identity = {
            "process": self.process,
            "instance": self.instance,
            "host": socket.gethostname(),
            "pid": os.getpid(),
            "started": self.started,
            "last_report": now,
            "ttl": self.instance_ttl,
        }
        pipe.hset(key, mapping={**gauges, **identity})
        pipe.expire(key, GONE_RETAIN_S)
        pipe.set(self.alive_key, now, px=max(1, int(self.instance_ttl * 1000)))

    def retire(self) -> None:
        """Say at once that this instance is gone (a clean stop), instead of after its TTL."""
        try:
            _client().delete(self.alive_key)
        except redis.RedisError as exc:
            log.warning("could not retire %s: %s", self.instance_key, exc)


def _add_refusals(pipe: redis.client.Pipeline, refusals: dict[tuple[str, str], int]) -> None:
    if not refusals:
        return
    args: list[str | int] = [settings.REFUSAL_DRONES]
    for (drone_id, reason), amount in refusals.items():
        args += [drone_id, reason, amount]
    args.append(OTHER_DRONES)
    pipe.eval(_ADD_REFUSALS, 2, REFUSALS_KEY, REFUSAL_DRONES_KEY, *args)


def refusals(client: redis.Redis | None = None) -> list[dict]:
    """Refused messages per drone, the most refused first: `{"drone_id", "total",
    "reasons": {reason: count}}`; `OTHER_DRONES` gathers the ids past the cap."""
    client = client or _client()
    by_drone: dict[str, dict[str, int]] = {}
    for field_name, value in client.hgetall(REFUSALS_KEY).items():
        drone_id, _, reason = field_name.partition("|")
        by_drone.setdefault(drone_id, {})[reason] = int(value)
    rows = [
        {
            "drone_id": drone_id,
            "total": sum(reasons.values()),
            "reasons": dict(sorted(reasons.items())),
        }
        for drone_id, reasons in by_drone.items()
    ]
    rows.sort(key=lambda row: (-row["total"], row["drone_id"]))
    return rows


class Heartbeat:
    """A daemon thread flushing a `Counters` every `flush_every` seconds, for processes
    (web, past view) that have nothing of their own to count but must be seen alive."""

    def __init__(self, counters: Counters) -> None:
        self.counters = counters
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name=f"heartbeat-{counters.process}", daemon=True
        )

    def start(self) -> Heartbeat:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(self.counters.flush_every + 2)
        self.counters.retire()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.counters.flush()
            self._stop.wait(self.counters.flush_every)


def is_alive(identity: str, client: redis.Redis) -> bool:
    """Whether the process with this `Counters.identity` still reports."""
    return bool(client.exists(ALIVE_PREFIX + identity))


def start_heartbeat(process: str, **options: float | str) -> Heartbeat:
    """Report this process as an instance of `process` until it exits."""
    return Heartbeat(Counters(process, **options)).start()  # type: ignore[arg-type]


def snapshot() -> dict[str, dict[str, float]]:
    """Every process's counters, for /health and the status page."""
    client = _client()
    out: dict[str, dict[str, float]] = {}
    for key in client.scan_iter(KEY_PREFIX + "*"):
        values = client.hgetall(key)
        out[key[len(KEY_PREFIX) :]] = {name: float(value) for name, value in values.items()}
    return out


@dataclass(frozen=True)
class Instance:
    """One process instance as last reported, and whether its heartbeat is still alive."""

    process: str
    instance: str
    host: str
    pid: int
    started: float
    last_report: float
    ttl: float
    alive: bool
    counters: dict[str, float]

    def as_dict(self) -> dict:
        return {
            "process": self.process,
            "instance": self.instance,
            "host": self.host,
            "pid": self.pid,
            "started": self.started,
            "last_report": self.last_report,
            "ttl": self.ttl,
            "alive": self.alive,
            "counters": self.counters,
        }


def instances(client: redis.Redis | None = None) -> list[Instance]:
    """Every instance still listed (alive, or gone within GONE_RETAIN_S), by process."""
    client = client or _client()
    keys = sorted(client.scan_iter(INSTANCE_PREFIX + "*", count=500))
    if not keys:
        return []
    pipe = client.pipeline(transaction=False)
    for key in keys:
        pipe.hgetall(key)
        pipe.exists(ALIVE_PREFIX + key[len(INSTANCE_PREFIX) :])
    results = pipe.execute()
    out = []
    for values, alive in zip(results[0::2], results[1::2], strict=True):
        if not values or "process" not in values:
            continue  # expired between the scan and the read
        numbers = {}
        for name, value in values.items():
            if name in IDENTITY_FIELDS:
                continue
            try:
                numbers[name] = float(value)
            except ValueError:
                continue
        out.append(
            Instance(
                process=values["process"],
                instance=values.get("instance", ""),
                host=values.get("host", ""),
                pid=int(float(values.get("pid", 0))),
                started=float(values.get("started", 0)),
                last_report=float(values.get("last_report", 0)),
                ttl=float(values.get("ttl", settings.INSTANCE_TTL_S)),
                alive=bool(alive),
                counters=numbers,
            )
        )
    out.sort(key=lambda i: (i.process, not i.alive, i.host, i.pid, i.instance))
    return out

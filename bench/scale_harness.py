"""Drive the whole ground side with a fleet of load drones and measure what an operator feels.

One run (`run_load`) starts what it needs on ports of its own and stops it all afterwards:
the test profile's PostgreSQL and Redis (scripts/services.sh, shared and idempotent) with a
database (`skyhive_loadtest`) and a Redis db index of our own; a private broker (Mosquitto,
or a RabbitMQ cluster through scripts/rabbitmq.sh); the ground processes (web, gateway,
ingest) as subprocesses; and N load drones (firmware.loaddrone) in a few processes.

It measures, with the fleet streaming:
- ingest lag: every second, per drone, how old the newest stored sample is (its `ts` is
  the drone's send time), so lag ≤ the figure (it includes up to one telemetry period);
- samples sent vs stored once the load stops and the ingest has drained;
- command round trip through the REST API, first with one drone and no fleet (baseline),
  then with the fleet connected;
- fleet-map staleness: on `/ws/fleet/`, the age of each drone update's position when it
  arrives (load drones drift on a circle whose phase is the time, see loaddrone);
- memory (RSS) of the ground processes and the broker, idle vs loaded, per connected drone.

    .venv/bin/python -m bench.scale_harness provision ...   (internal: runs inside Django)
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import secrets
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

import psutil

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from firmware.loaddrone import Account, grid_home, position_age  # noqa: E402
from runtime.processes import Supervised, port_open, python_env, wait_for  # noqa: E402
from workers.ground import GroundProcesses  # noqa: E402

PY = sys.executable
MANAGE = str(ROOT / "manage.py")
ORG = "loadtest"
DATABASE = "skyhive_loadtest"
REDIS_DB = 9  # the test Redis, but a db index nobody else uses: no shared groups or queues


@dataclass
class LoadConfig:
    drones: int = 1000
    broker: str = "mosquitto"  # or "rabbitmq"
    duration: float = 30.0  # seconds of measurement with the whole fleet streaming
    rate: float = 10.0  # telemetry Hz per drone
    heartbeat: float = 5.0  # seconds between heartbeats
    per_message: int = 1  # samples per telemetry message (the period is per_message / rate)
    connect_spread: float = 2.0  # seconds over which each load process connects its drones
    per_process: int = 250  # load drones per process
    webs: int = 1
    gateways: int = 1
    ingests: int = 1
    rabbit_nodes: int = 2
    command_interval: float = 0.2  # seconds between measured commands
    baseline_commands: int = 30
    mqtt_port: int = 18850  # the private Mosquitto
    rabbit_port_base: int = 19260  # the private RabbitMQ cluster (ports base+1 .. base+32)
    data_dir: Path = ROOT / ".data" / "loadtest"
    database: str = DATABASE  # on the test profile's PostgreSQL
    redis_db: int = REDIS_DB  # on the test profile's Redis
    quiet: bool = False


def percentile(values: list[float], q: float) -> float | None:
    """The q-quantile (0..1) by nearest rank; None for no values."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))]


@dataclass
class LoadResult:
    broker: str
    drones: int
    rate: float
    duration_s: float
    per_message: int = 1
    online: int = 0
    connect_s: float = 0.0
    lag_p50_s: float | None = None
    lag_p99_s: float | None = None
    lag_samples: int = 0
    sent: int = 0
    stored: int = 0
    ingest_per_s: float = 0.0  # rows stored per second while measured
    command_rtt_p50_s: float | None = None
    command_rtt_p99_s: float | None = None
    command_failures: int = 0
    commands: int = 0
    baseline_rtt_p50_s: float | None = None
    baseline_rtt_p99_s: float | None = None
    map_staleness_p50_s: float | None = None
    map_staleness_p99_s: float | None = None
    map_updates: int = 0
    map_drones: int = 0
    rss_idle_mib: dict[str, float] = field(default_factory=dict)
    rss_loaded_mib: dict[str, float] = field(default_factory=dict)
    cores: dict[str, float] = field(default_factory=dict)  # CPU cores busy while measured
    # Cores' worth of time each role's threads were runnable but waiting for a CPU:
    # high means starved by the machine, not held back by its own design.
    cpu_wait: dict[str, float] = field(default_factory=dict)
    load_average: tuple[float, float] = (0.0, 0.0)  # 1-min load average at start, end
    sent_per_s: float = 0.0  # samples the load drones sent per second while measured
    broker_figures: dict = field(default_factory=dict)  # the broker's own, while measured
    kib_per_drone: float | None = None
    load_stats: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def lost(self) -> int:
        return self.sent - self.stored

    def to_dict(self) -> dict:
        return dict(asdict(self), lost=self.lost)

    def summary(self) -> str:
        def s(v: float | None, unit: str = "s", scale: float = 1.0) -> str:
            return "n/a" if v is None else f"{v * scale:.3g} {unit}"

        lines = [
            f"{self.drones} load drones on {self.broker}, {self.rate:g} Hz telemetry"
            + (f" ({self.per_message} samples a message), " if self.per_message > 1 else ", ")
            + f"{self.duration_s:.0f} s measured ({self.online} online after {self.connect_s:.1f} s)",
            f"  ingest lag          p50 {s(self.lag_p50_s)}, p99 {s(self.lag_p99_s)} "
            f"({self.lag_samples} drone-seconds)",
            f"  samples             sent {self.sent}, stored {self.stored}, not stored after the "
            f"drain wait {self.lost}; "
            f"stored {self.ingest_per_s:.0f}/s of {self.sent_per_s:.0f}/s sent",
            f"  command round trip  p50 {s(self.command_rtt_p50_s, 'ms', 1e3)}, "
            f"p99 {s(self.command_rtt_p99_s, 'ms', 1e3)} ({self.commands} commands, "
            f"{self.command_failures} failed); no fleet: p50 "
            f"{s(self.baseline_rtt_p50_s, 'ms', 1e3)}, p99 {s(self.baseline_rtt_p99_s, 'ms', 1e3)}",
            f"  fleet-map staleness p50 {s(self.map_staleness_p50_s)}, "
            f"p99 {s(self.map_staleness_p99_s)} ({self.map_updates} updates, "
            f"{self.map_drones} drones)",
            "  memory (RSS MiB)    "
            + ", ".join(
                f"{k} {self.rss_idle_mib.get(k, 0):.0f}→{v:.0f}"
                for k, v in self.rss_loaded_mib.items()
            )
            + f"; {s(self.kib_per_drone, 'KiB')} per connected drone",
        ]
        lines.append(
            "  CPU (cores busy)    "
            + ", ".join(f"{k} {v:.2f}" for k, v in self.cores.items())
            + f" of {psutil.cpu_count()}"
        )
        if self.ingest_per_s and self.cores.get("ingest"):
            per_sample = self.cores["ingest"] / self.ingest_per_s * 1e6
            lines.append(
                f"  ingest CPU          {per_sample:.0f} µs per stored sample "
                f"(one busy core would hold {1e6 / per_sample:.0f} samples/s)"
            )
        if self.cpu_wait:
            lines.append(
                "  waiting for a CPU   "
                + ", ".join(f"{k} {v:.2f}" for k, v in self.cpu_wait.items())
                + " (cores' worth of runnable time not run)"
            )
        if self.broker_figures:
            lines.append(
                "  broker's figures    "
                + ", ".join(f"{k} {v}" for k, v in self.broker_figures.items())
            )
        lines.append(
            f"  load average        {self.load_average[0]:.2f} at the start, "
            f"{self.load_average[1]:.2f} at the end of the measured window"
        )
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)


# ---------------------------------------------------------------------------------------
# Services and settings.


_STARTED = time.monotonic()


def _say(config: LoadConfig, text: str) -> None:
    if not config.quiet:
        print(f"[loadtest {time.monotonic() - _STARTED:5.1f} s] {text}", flush=True)


def _read_env(path: Path) -> dict[str, str]:
    pairs = (line.split("=", 1) for line in path.read_text().splitlines() if "=" in line)
    return {k.strip(): v.strip() for k, v in pairs}


def _with_path(url: str, path: str) -> str:
    parts = urlsplit(url)
    return urlunsplit((parts.scheme, parts.netloc, path, parts.query, parts.fragment))


def _script(*argv: str, env: dict[str, str] | None = None, timeout: float = 240) -> str:
    result = subprocess.run(
        argv, cwd=ROOT, env={**os.environ, **(env or {})}, capture_output=True, text=True,
        timeout=timeout,
    )  # fmt: skip
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed:\n{result.stdout}\n{result.stderr}")
    return result.stdout


def database_and_redis(config: LoadConfig) -> dict[str, str]:
    """The test profile's PostgreSQL and Redis, with a database and db index of our own."""
    _script(str(ROOT / "scripts" / "services.sh"), "start", "test")
    # The profile the script just started: a test worker's own (DATA_DIR), else .data/test.
    profile = Path(os.environ.get("DATA_DIR") or ROOT / ".data" / "test")
    test_env = _read_env(profile / "env")
    import psycopg
    from psycopg import sql

    with psycopg.connect(test_env["DATABASE_URL"], autocommit=True) as conn:
        exists = conn.execute("SELECT 1 FROM pg_database WHERE datname = %s", (config.database,))
        if exists.fetchone() is None:
            conn.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(config.database)))
    redis_url = _with_path(test_env["REDIS_URL"], f"/{config.redis_db}")
    import redis

    redis.Redis.from_url(redis_url).flushdb()  # our db index only: stale outboxes, counters
    return {
        "DATABASE_URL": _with_path(test_env["DATABASE_URL"], f"/{config.database}"),
        "REDIS_URL": redis_url,
    }


class Broker:
    """The run's private broker; stops only what it started."""

    def __init__(self, config: LoadConfig) -> None:
        self.config = config
        self.kind = config.broker
        self.started = False
        self.data_dir = config.data_dir / self.kind
        self.script_env = {
            "DATA_DIR": str(self.data_dir),
            "MQTT_PORT": str(config.mqtt_port),
            # Its own drones' listener: never one inherited from the caller's profile.
            "MQTT_DRONE_PORT": str(config.mqtt_port + 1000),
            "RABBIT_PORT_BASE": str(config.rabbit_port_base),
        }

    def start(self) -> dict[str, str]:
        if self.kind == "mosquitto":
            self.started = not port_open(self.config.mqtt_port)
            _script(str(ROOT / "scripts" / "services.sh"), "mosquitto-start", "loadtest",
                    env=self.script_env)  # fmt: skip
            password = (self.data_dir / "secrets" / "mqtt_ground_password").read_text().strip()
            url = f"mqtt://ground:{password}@127.0.0.1:{self.config.mqtt_port}"
            # Drones have a listener of their own (scripts/services.sh, MQTT_DRONE_PORT).
            drones = self.script_env["MQTT_DRONE_PORT"]
            return {"MQTT_BROKER": "mosquitto", "MQTT_URL": url, "MQTT_URLS": url,
                    "MQTT_PUBLIC_PORT": drones,
                    "MOSQUITTO_DIR": str(self.data_dir / "mosquitto")}  # fmt: skip
        nodes = str(self.config.rabbit_nodes)
        self.started = not port_open(self.config.rabbit_port_base + 11)
        rabbit = str(ROOT / "scripts" / "rabbitmq.sh")
        _script(rabbit, "start", "loadtest", nodes, env=self.script_env)
        out = _script(rabbit, "env", "loadtest", nodes, env=self.script_env)
        env = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
        keys = ("MQTT_BROKER", "MQTT_URL", "MQTT_URLS", "AMQP_URLS", "RABBITMQ_API_URLS")
        purge_rabbit_queues(env["RABBITMQ_API_URLS"])
        return {k: env[k] for k in keys}

    def stop(self) -> None:
        if not self.started:
            return
        if self.kind == "mosquitto":
            _script(str(ROOT / "scripts" / "services.sh"), "mosquitto-stop", "loadtest",
                    env=self.script_env)  # fmt: skip
        else:
            _script(str(ROOT / "scripts" / "rabbitmq.sh"), "stop", "loadtest",
                    env=self.script_env)  # fmt: skip

    def processes(self) -> list[psutil.Process]:
        """The broker's OS processes, for memory figures."""
        found = []
        if self.kind == "mosquitto":
            pid_file = self.data_dir / "mosquitto" / "mosquitto.pid"
            with contextlib.suppress(OSError, ValueError, psutil.Error):
                found.append(psutil.Process(int(pid_file.read_text().strip())))
            return found
        for pid_file in sorted((self.data_dir / "rabbitmq").glob("*/pid")):
            with contextlib.suppress(OSError, ValueError, psutil.Error):
                found.append(psutil.Process(int(pid_file.read_text().strip())))
        return found


def _rabbit_api(api_urls: str, method: str, path: str) -> object:
    """Call the first management API node that answers; JSON back (None when empty)."""
    import base64
    import urllib.request

    error: OSError | None = None
    for api in api_urls.split(","):
        parts = urlsplit(api)
        auth = base64.b64encode(f"{parts.username}:{parts.password}".encode()).decode()
        url = f"http://{parts.hostname}:{parts.port}{parts.path}/{path}"
        request = urllib.request.Request(
            url, method=method, headers={"authorization": f"Basic {auth}"}
        )
        try:
            with urllib.request.urlopen(request, timeout=10) as response:
                raw = response.read()
        except OSError as exc:
            error = exc
            continue
        return json.loads(raw) if raw else None
    raise OSError(f"no RabbitMQ management API answered: {error}")


def rabbit_queue_depths(api_urls: str) -> dict[str, int]:
    """Messages waiting per ground queue (skyhive.*)."""
    try:
        queues = _rabbit_api(api_urls, "GET", "queues?columns=name,messages")
    except OSError:
        return {}
    return {
        q["name"]: int(q.get("messages") or 0)
        for q in queues  # type: ignore[attr-defined]
        if q["name"].startswith("skyhive.")
    }


def rabbit_queue_figures(api_urls: str) -> dict[str, float]:
    """The ingest queue as RabbitMQ counts it: waiting, in flight to consumers, and the
    totals published to it and delivered from it (rates come from several readings)."""
    try:
        q = _rabbit_api(api_urls, "GET", "queues/%2F/skyhive.ingest")
    except (OSError, ValueError):
        return {}
    if not isinstance(q, dict):
        return {}
    stats = q.get("message_stats") or {}
    return {
        "ready": float(q.get("messages_ready") or 0),
        "unacked": float(q.get("messages_unacknowledged") or 0),
        "consumers": float(q.get("consumers") or 0),
        "messages_published": float(stats.get("publish") or 0),
        "messages_delivered": float(stats.get("deliver_get") or 0),
    }


def purge_rabbit_queues(api_urls: str) -> None:
    """Empty the ground queues a previous run left, so this run's ingest reads only its own."""
    for name in rabbit_queue_depths(api_urls):
        _rabbit_api(api_urls, "DELETE", f"queues/%2F/{name}/contents")


def ground_env(config: LoadConfig, services: dict[str, str]) -> dict[str, str]:
    env = dict(os.environ)
    for key in ("DJANGO_ALLOW_ASYNC_UNSAFE", "TEST_WORKER_DB_NAME", "MQTT_URLS", "AMQP_URLS",
                "RABBITMQ_API_URLS"):  # fmt: skip
        env.pop(key, None)
    env.update(
        DJANGO_SETTINGS_MODULE="config.settings.base",
        DEBUG="false",
        SECRET_KEY=secrets.token_urlsafe(40),
        ALLOWED_HOSTS="127.0.0.1,localhost",
        DATA_DIR=str(config.data_dir),
        MEDIA_ROOT=str(config.data_dir / "media"),
        PYTHONUNBUFFERED="1",
        PYTHONPATH=str(ROOT),
        **services,
    )
    return env


# ---------------------------------------------------------------------------------------
# Provisioning runs inside Django, in a process of its own (each run has its own settings).


def provision_main(argv: list[str]) -> int:
    """Print (JSON) the run's drone accounts, their database ids, an API token and a
    session cookie for the operator."""
    parser = argparse.ArgumentParser(prog="scale_harness provision")
    parser.add_argument("--drones", type=int, required=True)
    args = parser.parse_args(argv)
    import django

    django.setup()
    from django.core.management import call_command

    call_command("migrate", "--noinput", verbosity=0)
    user, organisation = _operator()
    _start_empty(organisation)
    accounts, pks, seconds = _provision_drones(args.drones)
    token, cookie = _credentials_of(user)
    out = {"accounts": accounts, "pks": pks, "token": token, "cookie": cookie}
    json.dump({**out, "provision_s": seconds}, sys.stdout)
    return 0


def _operator():  # type: ignore[no-untyped-def]
    """The load test's organisation and its admin (created once)."""
    from django.contrib.auth import get_user_model

    from fleet.models import Membership, Organisation, Role

    organisation, _ = Organisation.objects.get_or_create(slug=ORG, defaults={"name": "Load test"})
    user, _ = get_user_model().objects.get_or_create(username="loadtest")
    Membership.objects.get_or_create(
        user=user, organisation=organisation, defaults={"role": Role.ADMIN}
    )
    return user, organisation


def _start_empty(organisation) -> None:  # type: ignore[no-untyped-def]
    """Our own database: each run starts empty and with every drone offline, so what is
    counted and seen online is this run's."""
    from django.db import connection

    from fleet.models import Drone

    with connection.cursor() as cursor:
        cursor.execute("TRUNCATE telemetry_sample")
    Drone.objects.filter(organisation=organisation).update(online=False)


def _credentials_of(user) -> tuple[str, str]:  # type: ignore[no-untyped-def]
    """The user's API token and a logged-in session cookie (for the fleet websocket)."""
    from django.contrib.auth import BACKEND_SESSION_KEY, HASH_SESSION_KEY, SESSION_KEY
    from django.contrib.sessions.backends.db import SessionStore
    from rest_framework.authtoken.models import Token

    token, _ = Token.objects.get_or_create(user=user)
    session = SessionStore()
    session[SESSION_KEY] = str(user.pk)
    session[BACKEND_SESSION_KEY] = "django.contrib.auth.backends.ModelBackend"
    session[HASH_SESSION_KEY] = user.get_session_auth_hash()
    session.save()
    return token.key, f"sessionid={session.session_key}"


def _provision_drones(count: int) -> tuple[list[dict], dict[str, int], float]:
    """(accounts, database id per drone id, seconds provisioning took)."""
    from django.db import connection

    from fleet import credentials

    ids = [f"LOAD_{i:04d}" for i in range(count)]
    began = time.perf_counter()
    issued = credentials.provision_many(ids, ORG)
    seconds = time.perf_counter() - began
    with connection.cursor() as cursor:
        cursor.execute("SELECT drone_id, id FROM fleet_drone WHERE drone_id = ANY(%s)", [ids])
        pks = dict(cursor.fetchall())
    accounts = []
    for i, c in enumerate(issued):
        urls = c.urls or (f"mqtt://{c.host}:{c.port}",)
        k = i % len(urls)  # spread the fleet over a cluster's nodes; the rest are fail-overs
        accounts.append(Account(c.drone_id, c.password, urls[k:] + urls[:k], grid_home(i)))
    return [a.to_dict() for a in accounts], pks, seconds


# ---------------------------------------------------------------------------------------
# Load drone processes.


class LoadProcess:
    """One `python -m firmware.loaddrone` process; its latest stats line is kept."""

    def __init__(self, accounts: list[Account], config: LoadConfig, folder: Path, name: str):
        self.path = folder / f"{name}.json"
        self.path.write_text(json.dumps([a.to_dict() for a in accounts]))
        self.latest: dict = {}
        self.final: dict | None = None
        argv = [PY, "-m", "firmware.loaddrone", "--fleet", str(self.path),
                "--rate", str(config.rate), "--heartbeat", str(config.heartbeat),
                "--stats-interval", "1", "--per-message", str(config.per_message),
                "--connect-spread", str(config.connect_spread)]  # fmt: skip
        self.process = Supervised(
            name, argv, python_env(), folder / f"{name}.log", on_line=self._line
        ).start()

    def _line(self, line: str) -> None:
        try:
            stats = json.loads(line)
        except ValueError:
            return  # a log line, not stats
        if not isinstance(stats, dict):
            return
        if stats.get("type") == "final":
            self.final = stats
        self.latest = stats

    @property
    def online(self) -> int:
        return int(self.latest.get("online", 0))

    def stop(self) -> dict:
        self.process.stop(20)
        return self.final or self.latest


def sum_stats(stats: list[dict]) -> dict:
    total: dict = {"dropped": {}}
    for item in stats:
        for key, value in item.items():
            if key == "dropped":
                for reason, n in value.items():
                    total["dropped"][reason] = total["dropped"].get(reason, 0) + n
            elif isinstance(value, int) and key != "ts":
                total[key] = total.get(key, 0) + value
    return total


# ---------------------------------------------------------------------------------------
# Measurements.


class LagProbe:
    """Every second, how old each drone's newest stored sample is (send time → visible)."""

    QUERY = (
        "SELECT d, (SELECT max(ts) FROM telemetry_sample s WHERE s.drone_id = d "
        "AND s.object = 'AttitudeActual' AND s.ts >= to_timestamp(%s)) "
        "FROM unnest(%s::bigint[]) AS d"
    )

    def __init__(self, conninfo: str, pks: list[int], since: float) -> None:
        self.conninfo = conninfo
        self.pks = pks
        self.since = since
        self.lags: list[float] = []
        self.missing = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> LagProbe:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)

    def _run(self) -> None:
        import psycopg

        with psycopg.connect(self.conninfo, autocommit=True) as conn:
            while not self._stop.wait(1.0):
                rows = conn.execute(self.QUERY, (self.since, self.pks)).fetchall()
                now = time.time()
                for _pk, newest in rows:
                    if newest is None:  # nothing stored yet: at least this old
                        self.missing += 1
                        self.lags.append(now - self.since)
                    else:
                        self.lags.append(now - newest.timestamp())


class MapProbe:
    """A logged-in `/ws/fleet/` client: the age of each drone update's position on arrival."""

    def __init__(self, url: str, cookie: str, homes: dict[str, tuple[float, float, float]]):
        self.url = url
        self.cookie = cookie
        self.homes = homes
        self.ages: list[float] = []
        self.drones: set[str] = set()
        self.snapshot_seen = threading.Event()
        self.error: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)

    def start(self) -> MapProbe:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)

    def reset(self) -> None:
        self.ages.clear()
        self.drones.clear()

    async def _run(self) -> None:
        import websockets
        from websockets.typing import Origin

        headers = {"Cookie": self.cookie}
        try:
            async with websockets.connect(
                self.url, additional_headers=headers, origin=Origin("http://127.0.0.1"),
                max_size=None, open_timeout=10,
            ) as ws:  # fmt: skip
                while not self._stop.is_set():
                    try:
                        raw = await asyncio.wait_for(ws.recv(), 0.5)
                    except TimeoutError:
                        continue
                    self._message(json.loads(raw), time.time())
        except Exception as exc:  # reported in the result, never fatal to the run
            self.error = f"{type(exc).__name__}: {exc}"

    def _message(self, message: dict, now: float) -> None:
        if message.get("type") == "snapshot":
            self.snapshot_seen.set()
            return
        drone = message.get("drone")
        if message.get("type") != "drone" or not isinstance(drone, dict):
            return
        drone_id = drone.get("drone_id")
        position = drone.get("position") or {}
        if isinstance(drone.get("ts"), int | float):  # the heartbeat's own time, when sent
            age: float | None = now - drone["ts"]
        elif drone_id in self.homes and "lat" in position:
            age = position_age(self.homes[drone_id], position["lat"], position["lon"], now)
        else:
            age = None
        if age is not None:
            self.ages.append(age)
            self.drones.add(str(drone_id))


class CommandProbe:
    """Sequential commands through the REST API to drones in turn; round trips in seconds."""

    def __init__(self, base_url: str, token: str, drone_ids: list[str], interval: float):
        import httpx

        self.client = httpx.Client(
            base_url=base_url, headers={"Authorization": f"Token {token}"}, timeout=30
        )
        self.drone_ids = drone_ids
        self.interval = interval
        self.rtts: list[float] = []
        self.failures: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def one(self, drone_id: str) -> None:
        began = time.perf_counter()
        try:
            response = self.client.post(
                f"/api/v1/drones/{drone_id}/commands/",
                json={"command": "objrequest", "params": {"value": "AttitudeActual"}},
            )
        except Exception as exc:
            self.failures.append(f"{type(exc).__name__}: {exc}")
            return
        elapsed = time.perf_counter() - began
        if response.status_code == 200 and response.json().get("ok"):
            self.rtts.append(elapsed)
        else:
            self.failures.append(f"{response.status_code} {response.text[:200]}")

    def run_count(self, count: int) -> None:
        for i in range(count):
            self.one(self.drone_ids[i % len(self.drone_ids)])

    def start(self) -> CommandProbe:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(40)
        self.client.close()

    def _run(self) -> None:
        i = 0
        while not self._stop.wait(self.interval):
            self.one(self.drone_ids[(i * 7919) % len(self.drone_ids)])  # spread over the fleet
            i += 1


def rss_mib(processes: dict[str, list[psutil.Process]]) -> dict[str, float]:
    """RSS per role, each process with its children (uvicorn/ingest workers)."""
    out = {}
    for role, procs in processes.items():
        total = 0
        for proc in procs:
            with contextlib.suppress(psutil.Error):
                total += proc.memory_info().rss
                for child in proc.children(recursive=True):
                    with contextlib.suppress(psutil.Error):
                        total += child.memory_info().rss
        out[role] = total / 2**20
    return out


def cpu_seconds(processes: dict[str, list[psutil.Process]]) -> dict[str, float]:
    """User + system CPU seconds per role so far, each process with its children."""
    out = {}
    for role, procs in processes.items():
        total = 0.0
        for proc in procs:
            for p in [proc, *_children(proc)]:
                with contextlib.suppress(psutil.Error):
                    times = p.cpu_times()
                    total += times.user + times.system
        out[role] = total
    return out


def waiting_seconds(processes: dict[str, list[psutil.Process]]) -> dict[str, float]:
    """Seconds each role's threads spent runnable, waiting for a CPU, so far (Linux
    schedstat; empty elsewhere). A thread that is behind yet mostly waits here is starved
    by the machine; one that is behind and neither runs nor waits is blocked on something."""
    out = {}
    for role, procs in processes.items():
        total = 0
        for proc in procs:
            for p in [proc, *_children(proc)]:
                for path in Path(f"/proc/{p.pid}/task").glob("*/schedstat"):
                    with contextlib.suppress(OSError, ValueError, IndexError):
                        total += int(path.read_text().split()[1])
        out[role] = total / 1e9
    return out if Path("/proc/self/schedstat").exists() else {}


def sent_so_far(loads: list[LoadProcess]) -> int:
    """Telemetry objects the load drones report sent (their latest stats lines)."""
    return sum(int(p.latest.get("telemetry_objects", 0)) for p in loads)


def broker_counters(services: dict[str, str]) -> dict[str, float]:
    """The broker's own running totals: Mosquitto's $SYS (as the gateways keep them in
    Redis), RabbitMQ's per-queue figures from its management API."""
    if "RABBITMQ_API_URLS" in services:
        return rabbit_queue_figures(services["RABBITMQ_API_URLS"])
    import redis

    from workers.broker.mosquitto_sys import remembered

    try:
        figures = remembered(redis.Redis.from_url(services["REDIS_URL"]))
    except redis.RedisError:
        return {}
    names = ("messages_received", "messages_sent", "messages_dropped")
    return {k: float(figures[k]) for k in names if isinstance(figures.get(k), int | float)}


def broker_window(readings: list[tuple[float, dict[str, float]]]) -> dict:
    """The broker's figures over a window of timed readings: a running total as a rate
    between the first and the last time it changed (Mosquitto's $SYS and RabbitMQ's
    statistics are refreshed only every few seconds, so the window's own ends would be
    off by up to one refresh), anything else as it ended."""
    out: dict[str, float] = {}
    last = readings[-1][1] if readings else {}
    for name, value in last.items():
        if not name.startswith("messages_"):
            out[name] = round(value, 1)
            continue
        label = name.removeprefix("messages_")
        changes, previous = [], None
        for at, figures in readings:
            if name in figures and figures[name] != previous:
                changes.append((at, figures[name]))
                previous = figures[name]
        if len(changes) >= 3:  # the first change may be the first reading, not a refresh
            (t0, v0), (t1, v1) = changes[1], changes[-1]
            out[f"{label}/s"] = round((v1 - v0) / (t1 - t0))
        else:
            out[f"{label} in all"] = round(value)
    return out


class BrokerWatch:
    """Reads the broker's own figures every half second while measured."""

    def __init__(self, services: dict[str, str], every: float = 0.5) -> None:
        self.services = services
        self.every = every
        self.readings: list[tuple[float, dict[str, float]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> BrokerWatch:
        self._thread.start()
        return self

    def stop(self) -> dict:
        self._stop.set()
        self._thread.join(15)
        return broker_window(self.readings)

    def _run(self) -> None:
        while not self._stop.is_set():
            figures = broker_counters(self.services)
            if figures:
                self.readings.append((time.monotonic(), figures))
            self._stop.wait(self.every)


def _children(proc: psutil.Process) -> list[psutil.Process]:
    try:
        return proc.children(recursive=True)
    except psutil.Error:
        return []


def online_in_database(conninfo: str, pks: list[int]) -> int:
    import psycopg

    with psycopg.connect(conninfo, autocommit=True) as conn:
        row = conn.execute(
            "SELECT count(*) FROM fleet_drone WHERE online AND id = ANY(%s)", (pks,)
        ).fetchone()
    return int(row[0]) if row else 0


def stored_since(conninfo: str, pks: list[int], since: float, until: float = 4e9) -> int:
    """Samples stored for these drones whose send time is in [since, until)."""
    import psycopg

    with psycopg.connect(conninfo, autocommit=True) as conn:
        row = conn.execute(
            "SELECT count(*) FROM telemetry_sample WHERE drone_id = ANY(%s) "
            "AND ts >= to_timestamp(%s) AND ts < to_timestamp(%s)",
            (pks, since, until),
        ).fetchone()
    return int(row[0]) if row else 0


# ---------------------------------------------------------------------------------------
# One run.


@dataclass
class Run:
    """One run's place, services and what it started (stopped in reverse by run_load)."""

    config: LoadConfig
    folder: Path
    result: LoadResult
    broker: Broker
    loads: list[LoadProcess] = field(default_factory=list)
    probes: list = field(default_factory=list)
    services: dict[str, str] = field(default_factory=dict)
    data: dict = field(default_factory=dict)  # what provisioning printed
    accounts: list[Account] = field(default_factory=list)
    pks: list[int] = field(default_factory=list)
    ground: GroundProcesses | None = None
    roles: dict[str, list[psutil.Process]] = field(default_factory=dict)
    began: float = 0.0  # wall time the first load drone started: samples since count

    @property
    def conninfo(self) -> str:
        return self.services["DATABASE_URL"]

    @property
    def web(self) -> str:
        assert self.ground is not None
        return self.ground.web_urls[0]

    def online(self, count: int | None = None) -> int:
        return online_in_database(self.conninfo, self.pks[:count])

    def stored(self, until: float = 4e9) -> int:
        return stored_since(self.conninfo, self.pks, self.began, until)


def _provision(run: Run, env: dict[str, str]) -> None:
    """The drones' accounts, made by `provision_main` in a process of the run's settings."""
    out = subprocess.run(
        [PY, "-m", "bench.scale_harness", "provision", "--drones", str(run.config.drones)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"provisioning failed:\n{out.stderr[-3000:]}")
    run.data = json.loads(out.stdout)
    run.result.notes.append(
        f"provisioned {run.config.drones} drones in {run.data['provision_s']:.2f} s"
    )
    run.accounts = [Account.from_dict(a) for a in run.data["accounts"]]
    run.pks = [run.data["pks"][a.drone_id] for a in run.accounts]


def _start_ground(run: Run, env: dict[str, str]) -> None:
    """Web, gateway and ingest processes (workers.ground), and who to weigh for memory."""
    config = run.config
    run.ground = GroundProcesses(run.folder, env, client_prefix="loadtest")
    run.ground.add(web=config.webs, gateways=config.gateways, ingests=config.ingests)
    run.ground.start(90)
    run.roles = {
        kind: [psutil.Process(p.pid) for p in run.ground.of_kind(kind) if p.pid]
        for kind in ("web", "gateway", "ingest")
    }
    run.roles["broker"] = run.broker.processes()


def _baseline(run: Run) -> None:
    """Command round trips to one drone with no fleet connected (the same command path)."""
    run.began = time.time()
    run.loads.append(LoadProcess(run.accounts[:1], run.config, run.folder, "load0"))
    if not wait_for(lambda: run.online(1) == 1, 30, interval=0.25):
        raise RuntimeError("the first load drone never came online")
    probe = CommandProbe(
        run.web, run.data["token"], [run.accounts[0].drone_id], run.config.command_interval
    )
    probe.run_count(5)  # warm-up: connections, first queries
    probe.rtts.clear()
    probe.run_count(run.config.baseline_commands)
    probe.client.close()
    run.result.baseline_rtt_p50_s = percentile(probe.rtts, 0.5)
    run.result.baseline_rtt_p99_s = percentile(probe.rtts, 0.99)


def _connect_fleet(run: Run) -> MapProbe:
    """The fleet map's websocket first, then every other load drone, until all are online."""
    config = run.config
    homes = {a.drone_id: a.home for a in run.accounts if a.home is not None}
    url = run.web.replace("http", "ws") + f"/ws/fleet/?org={ORG}"
    map_probe = MapProbe(url, run.data["cookie"], homes).start()
    run.probes.append(map_probe)
    _say(config, f"connecting {config.drones} load drones")
    began = time.monotonic()
    rest = run.accounts[1:]
    for k in range(0, len(rest), config.per_process):
        name = f"load{len(run.loads)}"
        run.loads.append(LoadProcess(rest[k : k + config.per_process], config, run.folder, name))
    wait_for(lambda: sum(p.online for p in run.loads) >= config.drones,
             60 + config.connect_spread, interval=0.25)  # fmt: skip
    wait_for(lambda: run.online() >= config.drones, 20, interval=1.0)
    run.result.connect_s = time.monotonic() - began
    run.result.online = run.online()
    _say(config, f"{run.result.online} drones online in {run.result.connect_s:.1f} s; measuring")
    time.sleep(3.0)  # let the first burst of online events settle
    return map_probe


def _measure(run: Run, map_probe: MapProbe) -> tuple[LagProbe, CommandProbe]:
    """The measured window: lag, commands and the map probe running, memory halfway,
    CPU and rows stored over the whole of it."""
    config, result = run.config, run.result
    busy = dict(run.roles, **{"load drones": [psutil.Process(p.process.pid) for p in run.loads]})
    cpu_before, wait_before = cpu_seconds(busy), waiting_seconds(busy)
    broker, sent_before = BrokerWatch(run.services).start(), sent_so_far(run.loads)
    load_before = os.getloadavg()[0]
    stored_at_start = run.stored()
    start = time.time()
    map_probe.reset()
    lag = LagProbe(run.conninfo, run.pks, run.began).start()
    ids = [a.drone_id for a in run.accounts]
    commands = CommandProbe(run.web, run.data["token"], ids, config.command_interval).start()
    run.probes += [lag, commands]
    time.sleep(config.duration / 2)
    result.rss_loaded_mib = rss_mib(run.roles)
    if "RABBITMQ_API_URLS" in run.services:
        depths = rabbit_queue_depths(run.services["RABBITMQ_API_URLS"])
        result.notes.append(f"queue depths mid-run: {depths}")
    time.sleep(config.duration / 2)
    seconds = time.time() - start
    cpu_after, wait_after = cpu_seconds(busy), waiting_seconds(busy)
    result.cores = {role: (cpu_after[role] - cpu_before.get(role, 0.0)) / seconds
                    for role in cpu_after}  # fmt: skip
    result.cpu_wait = {role: round((wait_after[role] - wait_before.get(role, 0.0)) / seconds, 2)
                       for role in wait_after}  # fmt: skip
    result.broker_figures = broker.stop()
    result.sent_per_s = (sent_so_far(run.loads) - sent_before) / seconds
    result.load_average = (load_before, os.getloadavg()[0])
    # Sustained throughput: rows the ingest wrote while measured, whenever they were sent
    # (a backlogged broker delivers old samples; they count, as the work was done).
    result.ingest_per_s = (run.stored() - stored_at_start) / seconds
    for probe in (commands, lag, map_probe):
        probe.stop()
    return lag, commands


def _drain(run: Run) -> None:
    """Stop the fleet, let the ingest drain, count what was sent and what arrived."""
    finals = [p.stop() for p in run.loads]
    run.loads.clear()
    stats = sum_stats(finals)
    run.result.load_stats = stats
    run.result.sent = stats.get("telemetry_objects", 0)
    # Until everything sent is stored, or the count has not moved for 3 s (a busy
    # machine can stall the ingest for a second without it being done) and no broker
    # queue holds any for the ingest, 120 s at most.
    stored, still = -1, 0
    for _ in range(120):
        now_stored = run.stored()
        still = still + 1 if now_stored == stored else 0
        stored = now_stored
        if stored >= run.result.sent or (still >= 3 and not _ingest_backlog(run)):
            break
        time.sleep(1.0)
    run.result.stored = stored


def _ingest_backlog(run: Run) -> int:
    """Messages RabbitMQ still holds for the ingest (0 on Mosquitto, which does not say)."""
    api = run.services.get("RABBITMQ_API_URLS")
    return rabbit_queue_depths(api).get("skyhive.ingest", 0) if api else 0


def _summarise(
    result: LoadResult, lag: LagProbe, commands: CommandProbe, map_probe: MapProbe
) -> None:
    result.lag_samples = len(lag.lags)
    result.lag_p50_s = percentile(lag.lags, 0.5)
    result.lag_p99_s = percentile(lag.lags, 0.99)
    if lag.missing:
        result.notes.append(
            f"{lag.missing} drone-seconds with no sample stored yet (counted as lag ≥ the "
            "time since the run began)"
        )
    result.commands = len(commands.rtts) + len(commands.failures)
    result.command_failures = len(commands.failures)
    result.command_rtt_p50_s = percentile(commands.rtts, 0.5)
    result.command_rtt_p99_s = percentile(commands.rtts, 0.99)
    if commands.failures:
        result.notes.append(f"first command failure: {commands.failures[0]}")
    result.map_updates = len(map_probe.ages)
    result.map_drones = len(map_probe.drones)
    result.map_staleness_p50_s = percentile(map_probe.ages, 0.5)
    result.map_staleness_p99_s = percentile(map_probe.ages, 0.99)
    if map_probe.error:
        result.notes.append(f"fleet websocket: {map_probe.error}")
    growth = sum(result.rss_loaded_mib.values()) - sum(result.rss_idle_mib.values())
    result.kib_per_drone = growth * 1024 / (result.online or 1)


def _stop_all(items: list) -> None:
    """Stop each item; one that fails does not keep the others running."""
    for item in items:
        try:
            item.stop()
        except Exception as exc:
            print(f"[loadtest] could not stop {item!r}: {exc}", file=sys.stderr)


def _stop_ground(run: Run) -> None:
    if run.ground is not None:
        run.ground.stop()


def run_load(config: LoadConfig) -> LoadResult:
    """One whole run; everything started is stopped, whatever happens."""
    config.data_dir.mkdir(parents=True, exist_ok=True)
    folder = Path(tempfile.mkdtemp(prefix=f"run-{config.broker}-", dir=config.data_dir))
    result = LoadResult(
        config.broker, config.drones, config.rate, config.duration, config.per_message
    )
    run = Run(config, folder, result, Broker(config))
    with contextlib.ExitStack() as stack:
        # Run in reverse: load drones, probes, ground processes, then the broker.
        stack.callback(run.broker.stop)
        stack.callback(_stop_ground, run)
        stack.callback(_stop_all, run.probes)
        stack.callback(_stop_all, run.loads)
        _say(config, f"services and {config.broker} (logs in {folder})")
        run.services = database_and_redis(config)
        run.services.update(run.broker.start())
        env = ground_env(config, run.services)
        _say(config, f"provisioning {config.drones} drones")
        _provision(run, env)
        _say(config, "starting the ground processes")
        _start_ground(run, env)
        time.sleep(2.0)
        result.rss_idle_mib = rss_mib(run.roles)
        _baseline(run)
        map_probe = _connect_fleet(run)
        lag, commands = _measure(run, map_probe)
        _drain(run)
        _summarise(result, lag, commands, map_probe)
    return result


def compare_runs(results: list[LoadResult]) -> str:
    """One line per run: the figures the goals name, side by side."""

    def f(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.2f}"

    lines = ["run  lag p50/p99 s  stored/s of sent/s  map p99 s  online  broker cores  load avg"]
    for n, r in enumerate(results, 1):
        lines.append(
            f"{n:3d}  {f(r.lag_p50_s):>5}/{f(r.lag_p99_s):<6}  {r.ingest_per_s:8.0f} of "
            f"{r.sent_per_s:<7.0f}  {f(r.map_staleness_p99_s):>9}  {r.online:6d}  "
            f"{r.cores.get('broker', 0.0):12.2f}  {r.load_average[0]:.1f}→{r.load_average[1]:.1f}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "provision":
        return provision_main(argv[1:])
    print("usage: python -m bench.scale_harness provision --drones N (see scripts/loadtest.py)")
    return 2


if __name__ == "__main__":
    sys.exit(main())

"""Drive the whole ground side with a fleet of load drones and measure what an operator feels.

One run (`run_load`) starts what it needs on ports of its own and stops it all afterwards:
the test profile's PostgreSQL and Redis (scripts/services.sh, shared and idempotent) with a
database (`skyhive_loadtest`) and a Redis db index of our own; a private broker (Mosquitto,
or a RabbitMQ cluster through scripts/rabbitmq.sh); the ground processes (web, gateway,
ingest) as subprocesses; and N load drones (onboard.loaddrone) in a few processes.

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
import signal
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

from onboard.loaddrone import Account, grid_home, position_age  # noqa: E402
from tests.support.ground import GroundProcess  # noqa: E402

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
            f"{self.drones} load drones on {self.broker}, {self.rate:g} Hz telemetry, "
            f"{self.duration_s:.0f} s measured ({self.online} online after {self.connect_s:.1f} s)",
            f"  ingest lag          p50 {s(self.lag_p50_s)}, p99 {s(self.lag_p99_s)} "
            f"({self.lag_samples} drone-seconds)",
            f"  samples             sent {self.sent}, stored {self.stored}, not stored after the "
            f"drain wait {self.lost}; "
            f"stored {self.ingest_per_s:.0f}/s",
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


def _port_open(port: int) -> bool:
    import socket

    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.3):
            return True
    except OSError:
        return False


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
    test_env = _read_env(ROOT / ".data" / "test" / "env")
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
            "RABBIT_PORT_BASE": str(config.rabbit_port_base),
        }

    def start(self) -> dict[str, str]:
        if self.kind == "mosquitto":
            self.started = not _port_open(self.config.mqtt_port)
            _script(str(ROOT / "scripts" / "services.sh"), "mosquitto-start", "loadtest",
                    env=self.script_env)  # fmt: skip
            password = (self.data_dir / "secrets" / "mqtt_ground_password").read_text().strip()
            url = f"mqtt://ground:{password}@127.0.0.1:{self.config.mqtt_port}"
            return {"MQTT_BROKER": "mosquitto", "MQTT_URL": url, "MQTT_URLS": url,
                    "MOSQUITTO_DIR": str(self.data_dir / "mosquitto")}  # fmt: skip
        nodes = str(self.config.rabbit_nodes)
        self.started = not _port_open(self.config.rabbit_port_base + 11)
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
    parser = argparse.ArgumentParser(prog="scale_harness provision")
    parser.add_argument("--drones", type=int, required=True)
    args = parser.parse_args(argv)
    import django

    django.setup()
    from django.contrib.auth import (
        BACKEND_SESSION_KEY,
        HASH_SESSION_KEY,
        SESSION_KEY,
        get_user_model,
    )
    from django.contrib.sessions.backends.db import SessionStore
    from django.core.management import call_command
    from rest_framework.authtoken.models import Token

    from fleet import credentials
    from fleet.models import Membership, Organisation, Role

    call_command("migrate", "--noinput", verbosity=0)
    organisation, _ = Organisation.objects.get_or_create(slug=ORG, defaults={"name": "Load test"})
    user, _ = get_user_model().objects.get_or_create(username="loadtest")
    Membership.objects.get_or_create(
        user=user, organisation=organisation, defaults={"role": Role.ADMIN}
    )
    token, _ = Token.objects.get_or_create(user=user)
    from django.db import connection

    from fleet.models import Drone

    # Our own database: start each run empty and with every drone offline, so what is
    # counted and seen online is this run's.
    with connection.cursor() as cursor:
        cursor.execute("TRUNCATE telemetry_sample")
    Drone.objects.filter(organisation=organisation).update(online=False)
    session = SessionStore()
    session[SESSION_KEY] = str(user.pk)
    session[BACKEND_SESSION_KEY] = "django.contrib.auth.backends.ModelBackend"
    session[HASH_SESSION_KEY] = user.get_session_auth_hash()
    session.save()
    ids = [f"LOAD_{i:04d}" for i in range(args.drones)]
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
    json.dump(
        {
            "accounts": [a.to_dict() for a in accounts],
            "pks": pks,
            "token": token.key,
            "cookie": f"sessionid={session.session_key}",
            "provision_s": seconds,
        },
        sys.stdout,
    )
    return 0


# ---------------------------------------------------------------------------------------
# Load drone processes.


class LoadProcess:
    """One `python -m onboard.loaddrone` process; its latest stats line is kept."""

    def __init__(self, accounts: list[Account], config: LoadConfig, folder: Path, name: str):
        self.path = folder / f"{name}.json"
        self.path.write_text(json.dumps([a.to_dict() for a in accounts]))
        self.latest: dict = {}
        self.final: dict | None = None
        argv = [PY, "-m", "onboard.loaddrone", "--fleet", str(self.path),
                "--rate", str(config.rate), "--heartbeat", str(config.heartbeat),
                "--stats-interval", "1"]  # fmt: skip
        self.log = open(folder / f"{name}.log", "wb")  # noqa: SIM115 - closed in stop()
        self.process = subprocess.Popen(
            argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=self.log, text=True,
            env=dict(os.environ, PYTHONPATH=str(ROOT)), start_new_session=True,
        )  # fmt: skip
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            try:
                stats = json.loads(line)
            except ValueError:
                continue
            if stats.get("type") == "final":
                self.final = stats
            self.latest = stats

    @property
    def online(self) -> int:
        return int(self.latest.get("online", 0))

    def stop(self) -> dict:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        self.reader.join(5)
        self.log.close()
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


def _wait(predicate, timeout: float, interval: float = 0.25) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return False


# ---------------------------------------------------------------------------------------
# One run.


def _start_ground(
    config: LoadConfig, env: dict[str, str], folder: Path, ground: dict[str, list[GroundProcess]]
) -> None:
    """Start web, gateway and ingest processes into `ground` (filled before anything waits,
    so the caller stops them even when one never becomes ready)."""
    from tests.support.ground import free_port

    ground.update(web=[], gateway=[], ingest=[])
    for i in range(config.webs):
        port = free_port()
        argv = [PY, "-m", "uvicorn", "config.asgi:application", "--host", "127.0.0.1",
                "--port", str(port), "--no-access-log"]  # fmt: skip
        ground["web"].append(GroundProcess(f"web{i + 1}", argv, env, folder / f"web{i + 1}.log",
                                           port=port))  # fmt: skip
    # On RabbitMQ the gateway's MQTT connection only publishes; messages come over AMQP.
    amqp = config.broker == "rabbitmq"
    gateway_ready = ("connected to", "consuming") if amqp else ("connected to",)
    ingest_ready = ("consuming",) if amqp else ("subscribed",)
    for i in range(config.gateways):
        name = f"gateway{i + 1}"
        argv = [PY, MANAGE, "gateway", "--client-id", f"loadtest-{name}"]
        ground["gateway"].append(
            GroundProcess(name, argv, env, folder / f"{name}.log", ready_text=gateway_ready)
        )
    for i in range(config.ingests):
        name = f"ingest{i + 1}"
        argv = [PY, MANAGE, "ingest_telemetry"]
        ground["ingest"].append(
            GroundProcess(name, argv, env, folder / f"{name}.log", ready_text=ingest_ready)
        )
    every = [p for procs in ground.values() for p in procs]
    for process in every:
        process.start()
    for process in every:
        process.wait_ready(90)


def _stop_ground(ground: dict[str, list[GroundProcess]]) -> None:
    _stop_all([p for procs in ground.values() for p in procs])


def _stop_all(items: list) -> None:
    """Stop each item; one that fails does not keep the others running."""
    for item in items:
        try:
            item.stop()
        except Exception as exc:
            print(f"[loadtest] could not stop {item!r}: {exc}", file=sys.stderr)


def run_load(config: LoadConfig) -> LoadResult:
    """One whole run; everything started is stopped, whatever happens."""
    result = LoadResult(config.broker, config.drones, config.rate, config.duration)
    config.data_dir.mkdir(parents=True, exist_ok=True)
    folder = Path(tempfile.mkdtemp(prefix=f"run-{config.broker}-", dir=config.data_dir))
    broker = Broker(config)
    ground: dict[str, list[GroundProcess]] = {}
    loads: list[LoadProcess] = []
    probes: list = []
    with contextlib.ExitStack() as stack:
        # Run in reverse: load drones, probes, ground processes, then the broker.
        stack.callback(broker.stop)
        stack.callback(_stop_ground, ground)
        stack.callback(_stop_all, probes)
        stack.callback(_stop_all, loads)
        _say(config, f"services and {config.broker} (logs in {folder})")
        services = database_and_redis(config)
        services.update(broker.start())
        env = ground_env(config, services)
        _say(config, f"provisioning {config.drones} drones")
        out = subprocess.run(
            [PY, "-m", "bench.scale_harness", "provision", "--drones", str(config.drones)],
            cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        if out.returncode != 0:
            raise RuntimeError(f"provisioning failed:\n{out.stderr[-3000:]}")
        data = json.loads(out.stdout)
        result.notes.append(f"provisioned {config.drones} drones in {data['provision_s']:.2f} s")
        accounts = [Account.from_dict(a) for a in data["accounts"]]
        pks = [data["pks"][a.drone_id] for a in accounts]
        conninfo = services["DATABASE_URL"]
        _say(config, "starting the ground processes")
        _start_ground(config, env, folder, ground)
        web = ground["web"][0].url
        roles = {
            "web": [psutil.Process(p.process.pid) for p in ground["web"] if p.process],
            "gateway": [psutil.Process(p.process.pid) for p in ground["gateway"] if p.process],
            "ingest": [psutil.Process(p.process.pid) for p in ground["ingest"] if p.process],
            "broker": broker.processes(),
        }
        time.sleep(2.0)
        result.rss_idle_mib = rss_mib(roles)

        # Baseline: one drone, no fleet, the same command path.
        run_start = time.time()
        loads.append(LoadProcess(accounts[:1], config, folder, "load0"))
        if not _wait(lambda: online_in_database(conninfo, pks[:1]) == 1, 30):
            raise RuntimeError("the first load drone never came online")
        baseline = CommandProbe(web, data["token"], [accounts[0].drone_id], config.command_interval)
        baseline.run_count(5)  # warm-up: connections, first queries
        baseline.rtts.clear()
        baseline.run_count(config.baseline_commands)
        baseline.client.close()
        result.baseline_rtt_p50_s = percentile(baseline.rtts, 0.5)
        result.baseline_rtt_p99_s = percentile(baseline.rtts, 0.99)

        # The fleet.
        homes = {a.drone_id: a.home for a in accounts if a.home is not None}
        map_probe = MapProbe(web.replace("http", "ws") + f"/ws/fleet/?org={ORG}", data["cookie"],
                             homes).start()  # fmt: skip
        probes.append(map_probe)
        _say(config, f"connecting {config.drones} load drones")
        began = time.monotonic()
        rest = accounts[1:]
        for k in range(0, len(rest), config.per_process):
            name = f"load{len(loads)}"
            loads.append(LoadProcess(rest[k : k + config.per_process], config, folder, name))
        _wait(lambda: sum(p.online for p in loads) >= config.drones, 60)
        _wait(lambda: online_in_database(conninfo, pks) >= config.drones, 20, 1.0)
        result.connect_s = time.monotonic() - began
        result.online = online_in_database(conninfo, pks)
        _say(config, f"{result.online} drones online in {result.connect_s:.1f} s; measuring")
        time.sleep(3.0)  # let the first burst of online events settle

        busy = dict(roles, **{"load drones": [psutil.Process(p.process.pid) for p in loads]})
        cpu_before = cpu_seconds(busy)
        stored_at_start = stored_since(conninfo, pks, run_start)
        measure_start = time.time()
        map_probe.reset()
        lag = LagProbe(conninfo, pks, run_start).start()
        probes.append(lag)
        commands = CommandProbe(web, data["token"], [a.drone_id for a in accounts],
                                config.command_interval).start()  # fmt: skip
        probes.append(commands)
        time.sleep(config.duration / 2)
        result.rss_loaded_mib = rss_mib(roles)
        if "RABBITMQ_API_URLS" in services:
            depths = rabbit_queue_depths(services["RABBITMQ_API_URLS"])
            result.notes.append(f"queue depths mid-run: {depths}")
        time.sleep(config.duration / 2)
        measure_end = time.time()
        stored_at_end = stored_since(conninfo, pks, run_start)
        cpu_after = cpu_seconds(busy)
        result.cores = {
            role: (cpu_after[role] - cpu_before.get(role, 0.0)) / (measure_end - measure_start)
            for role in cpu_after
        }
        commands.stop()
        lag.stop()
        map_probe.stop()

        # Stop the fleet, let the ingest drain, count what arrived.
        finals = [p.stop() for p in loads]
        loads.clear()
        stats = sum_stats(finals)
        result.load_stats = stats
        result.sent = stats.get("telemetry_objects", 0)
        stored = -1
        for _ in range(60):  # until the count stops moving (the ingest has drained)
            now_stored = stored_since(conninfo, pks, run_start)
            if now_stored == stored:
                break
            stored = now_stored
            time.sleep(1.0)
        result.stored = stored
        # Sustained throughput: rows the ingest wrote while measured, whenever they were sent
        # (a backlogged broker delivers old samples; they count, as the work was done).
        result.ingest_per_s = (stored_at_end - stored_at_start) / (measure_end - measure_start)

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
        connected = result.online or 1
        growth = sum(result.rss_loaded_mib.values()) - sum(result.rss_idle_mib.values())
        result.kib_per_drone = growth * 1024 / connected
    return result


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "provision":
        return provision_main(argv[1:])
    print("usage: python -m bench.scale_harness provision --drones N (see scripts/loadtest.py)")
    return 2


if __name__ == "__main__":
    sys.exit(main())

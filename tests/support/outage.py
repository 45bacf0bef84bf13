"""A ground of its own for outage tests: PostgreSQL, Redis and Mosquitto on free ports,
with the real `manage.py gateway` and a Celery worker pointed at them.

Stopping the suite's shared PostgreSQL or Redis would break every other test's
connections, so the database and Redis here are throw-away instances that a test may
stop and start at will: PostgreSQL initialised in a temporary directory (as the
`postgres` user when root, tests/telemetry/private_postgres.py) and migrated with
`manage.py migrate`; `redis-server` without persistence, restarted on the same port.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import psycopg

from config.queues import all_queues
from runtime.processes import REPO_ROOT, Supervised, free_port, python_env
from tests.support.celery_worker import consuming_worker
from tests.telemetry.private_postgres import PrivatePostgres, start_private_postgres
from workers.ground import gateway_argv
from workers.mosquitto import Broker, start_broker

REDIS_SERVER = shutil.which("redis-server") or "/usr/bin/redis-server"
DATABASE = "outage"
GROUND_PASSWORD = "outage-ground"


def celery_queues() -> str:
    """Every queue a task may be routed to, so one worker here runs them all."""
    return ",".join(all_queues())


@dataclass
class OutageGround:
    directory: Path
    drones: tuple[str, ...]
    postgres: PrivatePostgres | None = None
    broker: Broker | None = None
    redis: Supervised | None = None
    gateway: Supervised | None = None
    worker: Supervised | None = None
    env: dict[str, str] = field(default_factory=dict)

    @property
    def conninfo(self) -> str:
        assert self.postgres is not None
        return f"host=127.0.0.1 port={self.postgres.port} user=postgres dbname={DATABASE}"

    def start(self) -> OutageGround:
        self.postgres = start_private_postgres()
        with psycopg.connect(self.postgres.conninfo, autocommit=True) as conn:
            conn.execute(f"CREATE DATABASE {DATABASE}")
        users = {"ground": GROUND_PASSWORD, **{d: f"{d}-pw" for d in self.drones}}
        self.broker = start_broker(self.directory / "mosquitto", users)
        port = free_port()
        self.redis = Supervised(
            "redis",
            [
                REDIS_SERVER,
                "--port",
                str(port),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
            ],  # fmt: skip
            log_path=self.directory / "redis.log",
            port=port,
        )
        self.redis.start().wait_ready(20)
        self.env = self._environment(port)
        self.manage("migrate", "-v0")
        return self

    def _environment(self, redis_port: int) -> dict[str, str]:
        assert self.postgres is not None and self.broker is not None
        env = python_env(
            DJANGO_SETTINGS_MODULE="config.settings.test",
            DATABASE_URL=f"postgresql://postgres@127.0.0.1:{self.postgres.port}/{DATABASE}",
            REDIS_URL=f"redis://127.0.0.1:{redis_port}/0",
            CELERY_BROKER_URL=f"redis://127.0.0.1:{redis_port}/0",
            CELERY_RESULT_BACKEND=f"redis://127.0.0.1:{redis_port}/0",
            MQTT_URL=self.broker.url_for("ground"),
            MQTT_URLS=self.broker.url_for("ground"),
            MQTT_BROKER="mosquitto",
            MEDIA_ROOT=str(self.directory / "media"),
        )
        env.pop("TEST_WORKER_DB_NAME", None)  # this stack's database, not pytest's
        return env

    def manage(self, *args: str) -> str:
        done = subprocess.run(
            [sys.executable, str(REPO_ROOT / "manage.py"), *args],
            cwd=REPO_ROOT,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=180,
        )
        if done.returncode:
            raise RuntimeError(f"manage.py {' '.join(args)} failed: {done.stderr[-3000:]}")
        return done.stdout

    def scene(self, failing: str, spare: str) -> dict:
        """A mission `failing` flies, with `spare` ready to replace it (outage_scene)."""
        done = subprocess.run(
            [sys.executable, "-m", "tests.support.outage_scene", failing, spare],
            cwd=REPO_ROOT,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        if done.returncode:
            raise RuntimeError(f"outage scene failed: {done.stderr[-3000:]}")
        return json.loads(done.stdout.strip().splitlines()[-1])

    def start_ground(self) -> None:
        """The gateway (a persistent session, as `make run` starts it) and a worker."""
        self.gateway = Supervised(
            "gateway",
            gateway_argv("outage-gateway"),
            env=self.env,
            log_path=self.directory / "gateway.log",
            ready_text=("connected to",),
        )
        self.gateway.start()
        self.worker = consuming_worker(
            "outage", self.env, self.directory / "worker.log", queue=celery_queues()
        )
        self.gateway.wait_ready(60)

    def drone_url(self, drone_id: str) -> str:
        assert self.broker is not None
        return self.broker.url_for(drone_id)

    def stop_redis(self) -> None:
        assert self.redis is not None
        self.redis.stop()

    def start_redis(self) -> None:
        assert self.redis is not None
        self.redis.start().wait_ready(20)

    def query(self, sql: str, *params: object) -> list[tuple]:
        with psycopg.connect(self.conninfo, connect_timeout=3) as conn:
            return conn.execute(sql, params).fetchall()

    def reachable(self) -> bool:
        try:
            self.query("SELECT 1")
        except psycopg.OperationalError:
            return False
        return True

    def stop(self) -> None:
        for process in (self.gateway, self.worker, self.redis):
            if process is not None:
                process.stop()
        if self.broker is not None:
            self.broker.stop()
        if self.postgres is not None:
            self.postgres.destroy()

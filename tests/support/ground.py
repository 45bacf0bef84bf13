"""Replicated ground processes for tests: N web (uvicorn), gateways, ingests, Celery workers
and beat, each a real subprocess on the test database, each killable and restartable alone.

Every process reads the database pytest-django created (TEST_WORKER_DB_NAME, see
config/settings/test.py) and gets the same environment: the broker settings (a private
Mosquitto, or a RabbitCluster's `settings_env()`), a REDIS_URL, and a Celery queue of its
own, so engineers running other suites against the same Redis never take our tasks.
Each process runs in its own process group: `kill()` ends it and its children (a Celery
pool, an ingest supervisor's children) the way a crash would.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .paths import ROOT

MANAGE = str(ROOT / "manage.py")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _port_open(port: int) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.2):
            return True
    except OSError:
        return False


@dataclass
class GroundProcess:
    """One ground process: how to start it, and how to tell that it is ready."""

    name: str
    argv: list[str]
    env: dict[str, str]
    log_path: Path
    ready_text: str | None = None
    port: int | None = None
    process: subprocess.Popen | None = None
    starts: int = 0
    _log_offset: int = field(default=0, repr=False)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def start(self) -> GroundProcess:
        if self.alive:
            raise RuntimeError(f"{self.name} is already running")
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        # Readiness is judged on what this start writes, not on an earlier run's lines.
        self._log_offset = self.log_path.stat().st_size if self.log_path.exists() else 0
        with open(self.log_path, "ab") as log:
            self.process = subprocess.Popen(
                self.argv,
                cwd=ROOT,
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        self.starts += 1
        return self

    def output(self) -> str:
        """What this process wrote since its last start."""
        if not self.log_path.exists():
            return ""
        with open(self.log_path, "rb") as log:
            log.seek(self._log_offset)
            return log.read().decode(errors="replace")

    def is_ready(self) -> bool:
        if not self.alive:
            return False
        if self.port is not None and not _port_open(self.port):
            return False
        return self.ready_text is None or self.ready_text in self.output()

    def wait_ready(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.is_ready():
                return
            if self.process is not None and self.process.poll() is not None:
                raise RuntimeError(f"{self.name} exited early:\n{self.output()[-3000:]}")
            time.sleep(0.1)
        raise RuntimeError(f"{self.name} not ready in {timeout:.0f} s:\n{self.output()[-3000:]}")

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """End the whole process group with `sig` (SIGKILL: a crash, nothing drained)."""
        if self.process is None:
            return
        try:
            os.killpg(self.process.pid, sig)
        except ProcessLookupError:
            pass
        if sig == signal.SIGKILL:
            self.process.wait(10)

    def stop(self, timeout: float = 15.0) -> None:
        """SIGTERM to the leader (each process drains on it), then nothing of its group
        outlives it."""
        if self.process is None:
            return
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                pass
        self.kill(signal.SIGKILL)

    def restart(self, timeout: float = 60.0) -> None:
        if self.alive:
            self.stop()
        self.start().wait_ready(timeout)


class GroundProcesses:
    """A replicated ground: add processes, start them, kill or restart single ones.

    `env` overrides the environment of every process (MQTT_URL, MQTT_BROKER, MQTT_URLS,
    AMQP_URLS, REDIS_URL, CELERY_VISIBILITY_TIMEOUT, ...). `queue` is this ground's Celery
    queue; set it as the test process's default queue too when the test sends tasks.
    """

    def __init__(
        self,
        directory: Path,
        database_name: str,
        env: dict[str, str] | None = None,
    ) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.queue = f"repl-{uuid.uuid4().hex[:10]}"
        base = dict(os.environ)
        # Playwright's tests set this in the pytest process; ground processes are not async-unsafe.
        base.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)
        base.update(
            DJANGO_SETTINGS_MODULE="config.settings.test",
            TEST_WORKER_DB_NAME=database_name,
            PYTHONUNBUFFERED="1",
            PYTHONPATH=str(ROOT),
            CELERY_TASK_DEFAULT_QUEUE=self.queue,
        )
        base.update(env or {})
        self.env = base
        self.processes: dict[str, GroundProcess] = {}

    # -- what to run ------------------------------------------------------------------------

    def _add(self, kind: str, make: Callable[[str], GroundProcess]) -> GroundProcess:
        count = sum(1 for name in self.processes if name.rstrip("0123456789") == kind)
        name = f"{kind}{count + 1}"
        process = make(name)
        self.processes[name] = process
        return process

    def _log(self, name: str) -> Path:
        return self.directory / f"{name}.log"

    def add_web(self) -> GroundProcess:
        def make(name: str) -> GroundProcess:
            port = free_port()
            argv = [sys.executable, "-m", "uvicorn", "config.asgi:application",
                    "--host", "127.0.0.1", "--port", str(port), "--no-access-log",
                    "--lifespan", "off"]  # fmt: skip
            return GroundProcess(name, argv, self.env, self._log(name), port=port)

        return self._add("web", make)

    def add_gateway(self) -> GroundProcess:
        def make(name: str) -> GroundProcess:
            # A stable client id per instance: its persistent session survives a restart.
            argv = [sys.executable, MANAGE, "gateway", "--client-id", f"{self.queue}-{name}"]
            return GroundProcess(name, argv, self.env, self._log(name), ready_text="connected")

        return self._add("gateway", make)

    def add_ingest(self) -> GroundProcess:
        def make(name: str) -> GroundProcess:
            argv = [sys.executable, MANAGE, "ingest_telemetry"]
            return GroundProcess(name, argv, self.env, self._log(name), ready_text="subscribed")

        return self._add("ingest", make)

    def add_worker(self, pool: str = "solo", concurrency: int = 1) -> GroundProcess:
        def make(name: str) -> GroundProcess:
            argv = [sys.executable, "-m", "celery", "-A", "config", "worker",
                    "--pool", pool, "--concurrency", str(concurrency), "-Q", self.queue,
                    "-n", f"{name}-{self.queue}@%h", "-l", "info",
                    "--without-heartbeat", "--without-gossip", "--without-mingle"]  # fmt: skip
            return GroundProcess(name, argv, self.env, self._log(name), ready_text=" ready.")

        return self._add("worker", make)

    def add_beat(self) -> GroundProcess:
        def make(name: str) -> GroundProcess:
            schedule = self.directory / f"{name}-schedule"
            argv = [sys.executable, "-m", "celery", "-A", "config", "beat", "-l", "info",
                    "--schedule", str(schedule)]  # fmt: skip
            return GroundProcess(name, argv, self.env, self._log(name), ready_text="Starting")

        return self._add("beat", make)

    def add(
        self, *, web: int = 0, gateways: int = 0, ingests: int = 0, workers: int = 0,
        beat: bool = False,
    ) -> GroundProcesses:  # fmt: skip
        for _ in range(web):
            self.add_web()
        for _ in range(gateways):
            self.add_gateway()
        for _ in range(ingests):
            self.add_ingest()
        for _ in range(workers):
            self.add_worker()
        if beat:
            self.add_beat()
        return self

    # -- lifecycle ---------------------------------------------------------------------------

    def start(self, timeout: float = 90.0) -> GroundProcesses:
        """Start every process not running yet (all at once), then wait until all are ready."""
        pending = [p for p in self.processes.values() if not p.alive]
        for process in pending:
            process.start()
        deadline = time.monotonic() + timeout
        for process in pending:
            process.wait_ready(max(1.0, deadline - time.monotonic()))
        return self

    def __getitem__(self, name: str) -> GroundProcess:
        return self.processes[name]

    def of_kind(self, kind: str) -> list[GroundProcess]:
        return [p for n, p in self.processes.items() if n.rstrip("0123456789") == kind]

    @property
    def web_urls(self) -> list[str]:
        return [p.url for p in self.of_kind("web")]

    def kill(self, name: str) -> None:
        self.processes[name].kill()

    def restart(self, name: str, timeout: float = 60.0) -> None:
        self.processes[name].restart(timeout)

    def stop(self) -> None:
        for process in reversed(list(self.processes.values())):
            process.stop()

    def describe(self) -> str:
        """Each process's state and last lines, for assertion messages."""
        parts = []
        for name, process in self.processes.items():
            state = "alive" if process.alive else "down"
            tail = "\n    ".join(process.output().splitlines()[-8:])
            parts.append(f"{name} ({state}):\n    {tail}")
        return "\n".join(parts)


# -- simulated drones ---------------------------------------------------------------------


@dataclass
class SimulatedDrone:
    """A software flight controller (firmware.sim on a pty) and the real onboard agent."""

    drone_id: str
    folder: Path
    broker_url: str
    sim: object = None
    agent: subprocess.Popen | None = None

    def stop(self) -> None:
        if self.agent is not None and self.agent.poll() is None:
            self.agent.terminate()
            try:
                self.agent.wait(10)
            except subprocess.TimeoutExpired:
                self.agent.kill()
                self.agent.wait()
        if self.sim is not None:
            self.sim.stop()  # type: ignore[attr-defined]


def start_simulated_drone(
    folder: Path,
    drone_id: str,
    broker_url: str,
    home: tuple[float, float, float],
    *,
    time_scale: float,
    heartbeat_interval: float = 0.3,
    extra: list[str] | tuple[str, ...] = (),
) -> SimulatedDrone:
    """Start one drone; `broker_url` carries its credentials (several nodes: comma-separated)."""
    import shutil

    from firmware.sim import start_simulator
    from onboard.launcher import GEAR_EXAMPLE

    folder.mkdir(parents=True, exist_ok=True)
    shutil.copytree(GEAR_EXAMPLE, folder / "gear")
    drone = SimulatedDrone(drone_id, folder, broker_url)
    drone.sim = start_simulator(
        home=home,
        time_scale=time_scale,
        arming_line=folder / "arming_line",
        log_file=folder / "sim.log",
    )
    link = drone.sim.url  # type: ignore[attr-defined]
    argv = [sys.executable, "-m", "onboard", "--drone-id", drone_id, "--link", link,
            "--broker", broker_url, "--arming", f"sim-line:{folder / 'arming_line'}",
            "--gear-dir", str(folder / "gear"), "--log-dir", str(folder / "logs"),
            "--time-scale", str(time_scale), "--heartbeat-interval", str(heartbeat_interval),
            *extra]  # fmt: skip
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with open(folder / "agent.log", "ab") as log:
        drone.agent = subprocess.Popen(
            argv,
            stdout=subprocess.DEVNULL,
            stderr=log,
            cwd=ROOT,
            env=env,
        )
    return drone

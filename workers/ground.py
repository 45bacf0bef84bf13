"""The ground's processes as supervised subprocesses: web (ASGI under uvicorn), the MQTT
gateway, the telemetry ingest, the past-view service, Celery workers and beat.

`make run` starts one of each; `GroundProcesses` starts any number of each (a replicated
ground) for the load test and the fault tests, each killable and restartable alone. Every
process gets the same environment (settings module, database, broker, Redis), given by
the caller.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from pathlib import Path

from runtime.processes import REPO_ROOT, Supervised, free_port

MANAGE = str(REPO_ROOT / "manage.py")
# Worker-to-worker chatter nothing here reads; without it a worker starts faster.
NO_CHATTER = ("--without-heartbeat", "--without-gossip", "--without-mingle")
KINDS = ("web", "gateway", "ingest", "worker", "beat")
# Starts of a web server whose free port another process took before it bound it.
WEB_PORT_TRIES = 3


def web_argv(port: int) -> list[str]:
    return [sys.executable, "-m", "uvicorn", "config.asgi:application",
            "--host", "127.0.0.1", "--port", str(port), "--no-access-log"]  # fmt: skip


def gateway_argv(client_id: str | None = None) -> list[str]:
    """A stable client id per instance keeps its persistent session across restarts."""
    return [sys.executable, MANAGE, "gateway", *(["--client-id", client_id] if client_id else [])]


def ingest_argv() -> list[str]:
    return [sys.executable, MANAGE, "ingest_telemetry"]


def pastview_argv() -> list[str]:
    return [sys.executable, MANAGE, "pastview"]


def worker_argv(
    name: str,
    *,
    queue: str | None = None,
    loglevel: str = "warning",
    pool: str = "solo",
    concurrency: int | None = None,
    chatter: bool = True,
) -> list[str]:
    """`celery -A config worker` named `name` (`%h` is the host), on `queue` if given."""
    argv = [sys.executable, "-m", "celery", "-A", "config", "worker", "--pool", pool]
    if concurrency is not None:
        argv += ["--concurrency", str(concurrency)]
    if queue is not None:
        argv += ["-Q", queue]
    argv += ["-l", loglevel, "-n", name]
    if not chatter:
        argv += NO_CHATTER
    return argv


def beat_argv(schedule: Path) -> list[str]:
    return [sys.executable, "-m", "celery", "-A", "config", "beat", "-l", "info",
            "--schedule", str(schedule)]  # fmt: skip


def ready_text(kind: str, amqp: bool) -> tuple[str, ...]:
    """What a process of `kind` logs once it is serving. On RabbitMQ the gateway's MQTT
    connection only publishes and both consume AMQP queues (workers.broker). A web server
    says it is running only once it holds its port: its port taking connections alone
    could be another process's."""
    return {
        "web": ("Uvicorn running on",),
        "gateway": ("connected to", "consuming") if amqp else ("connected to",),
        "ingest": ("consuming",) if amqp else ("subscribed",),
        "worker": (" ready.",),
        "beat": ("Starting",),
    }.get(kind, ())


class GroundProcesses:
    """A replicated ground: add processes, start them, kill or restart single ones.

    `env` is every process's whole environment (MQTT_URL, MQTT_BROKER, MQTT_URLS,
    AMQP_URLS, REDIS_URL, ...); `queue`, when given, is the only Celery queue the workers
    consume; gateways are named `<client_prefix>-<name>` on the broker.
    """

    def __init__(
        self,
        directory: Path,
        env: Mapping[str, str],
        *,
        queue: str | None = None,
        client_prefix: str = "ground",
    ) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.env = dict(env)
        self.queue = queue
        self.client_prefix = client_prefix
        self.processes: dict[str, Supervised] = {}

    @property
    def amqp(self) -> bool:
        """RabbitMQ: the gateways and ingests consume shared AMQP queues (workers.broker)."""
        return self.env.get("MQTT_BROKER") == "rabbitmq"

    # -- what to run ------------------------------------------------------------------------

    def _add(
        self, kind: str, make: Callable[[str], list[str]], port: int | None = None
    ) -> Supervised:
        name = f"{kind}{len(self.of_kind(kind)) + 1}"
        process = Supervised(
            name,
            make(name),
            self.env,
            self.directory / f"{name}.log",
            ready_text=ready_text(kind, self.amqp),
            port=port,
        )
        self.processes[name] = process
        return process

    def add_web(self) -> Supervised:
        port = self._free_port()
        return self._add("web", lambda _: web_argv(port), port)

    def _free_port(self) -> int:
        """A free port none of these processes was given: the OS may hand the same free
        port out twice while neither is bound yet."""
        given = {process.port for process in self.processes.values()}
        while (port := free_port()) in given:
            pass
        return port

    def add_gateway(self) -> Supervised:
        return self._add("gateway", lambda name: gateway_argv(f"{self.client_prefix}-{name}"))

    def add_ingest(self) -> Supervised:
        return self._add("ingest", lambda _: ingest_argv())

    def add_worker(self, pool: str = "solo", concurrency: int = 1) -> Supervised:
        def argv(name: str) -> list[str]:
            return worker_argv(f"{name}-{self.client_prefix}@%h", queue=self.queue,
                               loglevel="info", pool=pool, concurrency=concurrency,
                               chatter=False)  # fmt: skip

        return self._add("worker", argv)

    def add_beat(self) -> Supervised:
        return self._add("beat", lambda name: beat_argv(self.directory / f"{name}-schedule"))

    def add(
        self, *, web: int = 0, gateways: int = 0, ingests: int = 0, workers: int = 0,
        beat: bool = False,
    ) -> GroundProcesses:  # fmt: skip
        for count, add in ((web, self.add_web), (gateways, self.add_gateway),
                           (ingests, self.add_ingest), (workers, self.add_worker),
                           (int(beat), self.add_beat)):  # fmt: skip
            for _ in range(count):
                add()
        return self

    # -- lifecycle ---------------------------------------------------------------------------

    def start(self, timeout: float = 90.0) -> GroundProcesses:
        """Start every process not running yet (all at once), then wait until all are ready."""
        import time

        pending = [p for p in self.processes.values() if not p.alive]
        for process in pending:
            process.start()
        deadline = time.monotonic() + timeout
        for process in pending:
            self._wait_ready(process, deadline)
        return self

    def _wait_ready(self, process: Supervised, deadline: float) -> None:
        """Wait until `process` is ready. A web server's port is chosen free before it
        binds it, and another process may take it between the two: such a server starts
        again on another free port, a few times at most."""
        import time

        for attempt in range(WEB_PORT_TRIES):
            try:
                process.wait_ready(max(1.0, deadline - time.monotonic()))
                return
            except RuntimeError:
                taken = "address already in use" in process.output()[-3000:]
                last = attempt == WEB_PORT_TRIES - 1
                if last or process.alive or not taken or not process.name.startswith("web"):
                    raise
            process.port = self._free_port()
            process.argv = web_argv(process.port)
            process.start()

    def __getitem__(self, name: str) -> Supervised:
        return self.processes[name]

    def of_kind(self, kind: str) -> list[Supervised]:
        return [p for n, p in self.processes.items() if n.rstrip("0123456789") == kind]

    @property
    def web_urls(self) -> list[str]:
        return [p.url for p in self.of_kind("web")]

    def kill(self, name: str) -> None:
        self.processes[name].kill()

    def restart(self, name: str, timeout: float = 60.0) -> None:
        self.processes[name].restart(timeout)

    def stop(self) -> None:
        """Stop each process, the last added first; one that fails does not keep the
        others running."""
        for process in reversed(list(self.processes.values())):
            try:
                process.stop()
            except Exception as exc:
                print(f"could not stop {process.name}: {exc}", file=sys.stderr)

    def describe(self) -> str:
        """Each process's state and last lines, for assertion messages."""
        parts = []
        for name, process in self.processes.items():
            state = "alive" if process.alive else "down"
            tail = "\n    ".join(process.output().splitlines()[-8:])
            parts.append(f"{name} ({state}):\n    {tail}")
        return "\n".join(parts)

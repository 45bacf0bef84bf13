#!/usr/bin/env python
"""Run the whole platform in the foreground (what `make run` ends in): one line per process
as it starts, then only warnings, errors and the drones' important events, prefixed with
the process's name; each process's whole output goes to .data/run/logs/<name>.log
(scripts/runlog.py).

Starts the project's services if they are not running, migrates, brings the broker's drone
users to their current form, creates the demo account,
then web (ASGI), the MQTT gateway, telemetry ingest, one Celery worker per queue
(safety, logs, default) and beat, and optionally N simulated drones. Ctrl-C stops everything this script started, and nothing
else.

Whatever ends this script, even SIGKILL, ends what it started: scripts/reaper.py, started
first, watches a pipe only this script holds and ends every process group it was told of
when the pipe closes (SIGTERM, SIGKILL after reaper.GRACE_S s). A Celery worker whose
Redis is gone ignores SIGTERM; it is killed STOP_GRACE_S s (Ctrl-C) or reaper.GRACE_S s
(supervisor killed) after it was asked to stop.

`--profile test` runs the same processes on the test settings and the services the
environment names (the tests' own), without starting services, migrating or creating the
demo account.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from runtime.processes import Supervised  # noqa: E402
from runtime.stopsignal import StopSignal  # noqa: E402
from scripts.reaper import GRACE_S  # noqa: E402
from scripts.runlog import LOG_DIR, ProcessOutput  # noqa: E402
from workers.ground import (  # noqa: E402
    MANAGE,
    beat_argv,
    gateway_argv,
    ingest_argv,
    pastview_argv,
    web_argv,
    worker_argv,
)

PY = str(ROOT / ".venv" / "bin" / "python")
COLOURS = ["36", "33", "35", "32", "34", "31", "96", "93"]
WIDTH = 8  # the name column of the prefixed output
# Ctrl-C: how long every process has to drain before what is left of its group is killed.
STOP_GRACE_S = 15.0
assert GRACE_S <= STOP_GRACE_S  # killed or not, the supervisor waits no longer than this
# One Celery worker per queue (config/queues.py routes tasks; docs/scaling.md): safety
# work never waits behind a log import, and a log that crashes its worker touches nothing
# else. The names are the settings' defaults unless the environment gives others.
WORKERS = [
    ("safety", os.environ.get("SAFETY_TASK_QUEUE") or "safety", 2),
    ("logs", os.environ.get("LOGS_IMPORT_QUEUE") or "logs", 1),
    ("worker", os.environ.get("CELERY_TASK_DEFAULT_QUEUE") or "celery", 1),
]


def command_exists(name: str) -> bool:
    return any(ROOT.glob(f"*/management/commands/{name}.py"))


def services_down() -> bool:
    out = subprocess.run(
        [str(ROOT / "scripts" / "services.sh"), "status", "run"],
        capture_output=True,
        text=True,
    ).stdout
    return "down" in out


class Foreground:
    """The processes `make run` started, their output prefixed on ours; the first to exit
    on its own (or Ctrl-C) stops them all."""

    def __init__(self, env: dict[str, str], log_dir: Path = LOG_DIR) -> None:
        self.env = env
        self.log_dir = log_dir
        self.processes: list[Supervised] = []
        self.stopping = threading.Event()
        # Our own session: the signal that ends our terminal's group does not end it.
        self.reaper = subprocess.Popen(
            [PY, str(ROOT / "scripts" / "reaper.py")],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            start_new_session=True,
            text=True,
        )

    def start(self, name: str, argv: list[str]) -> None:
        colour = COLOURS[len(self.processes) % len(COLOURS)]
        plain = f"{name:<{WIDTH}}| "
        prefix = f"\033[{colour}m{name:<{WIDTH}}|\033[0m " if sys.stdout.isatty() else plain
        output = ProcessOutput(name, prefix, self.log_dir)

        def exited(code: int) -> None:
            if not self.stopping.is_set():
                output.exited(code)
                output.write("stopping everything")
                self.stopping.set()

        process = Supervised(
            name, argv, self.env, log_path=output.log_path, on_line=output.on_line, on_exit=exited
        )
        self.processes.append(process.start())
        self._tell_reaper(process.pid)
        output.started(process.pid)

    def _tell_reaper(self, group: int | None) -> None:
        """Supervised starts each process as the leader of its own group: pid = group."""
        assert self.reaper.stdin is not None
        self.reaper.stdin.write(f"{group}\n")
        self.reaper.stdin.flush()

    def stop(self) -> None:
        """SIGTERM to each leader (Celery and uvicorn stop their own children cleanly),
        15 s for all of them, then nothing of any group outlives it."""
        self.stopping.set()
        for process in self.processes:
            if process.alive:
                process.process.terminate()  # type: ignore[union-attr]
        for process in self.processes:
            process.stop(STOP_GRACE_S)
        assert self.reaper.stdin is not None
        self.reaper.stdin.close()  # nothing left for it to end: it exits at once
        self.reaper.wait(STOP_GRACE_S)


def prepare(web_port: int, profile: str) -> tuple[bool, dict[str, str]]:
    """Start the services if they are down, migrate, create the demo account: (whether we
    started the services, the environment of every process). The test profile does none
    of it: its services and database are the tests'."""
    if profile == "test":
        return False, dict(
            os.environ, DJANGO_SETTINGS_MODULE="config.settings.test", PYTHONUNBUFFERED="1"
        )
    started_services = services_down()
    if started_services:
        subprocess.run([str(ROOT / "scripts" / "services.sh"), "start", "run"], check=True)
    env = dict(os.environ, DJANGO_SETTINGS_MODULE="config.settings.local", PYTHONUNBUFFERED="1")
    manage = [PY, MANAGE]
    subprocess.run([*manage, "migrate", "--noinput", "-v", "0"], check=True, env=env)
    # Drone users a broker kept from an earlier form (on RabbitMQ: a password of their own,
    # which logs in under any client id) are brought to the current one; none left, no change.
    subprocess.run([*manage, "provision_drone", "--upgrade"], check=True, env=env)
    url = f"http://127.0.0.1:{web_port}/"
    subprocess.run([*manage, "bootstrap_demo", "--url", url], check=True, env=env)
    return started_services, env


def start_platform(run: Foreground, web_port: int, drones: int, data_dir: Path) -> None:
    """One of each ground process, and the simulated drones when asked for."""
    run.start("web", with_python(web_argv(web_port)))
    if command_exists("gateway"):
        run.start("gateway", with_python(gateway_argv()))
    if command_exists("ingest_telemetry"):
        run.start("ingest", with_python(ingest_argv()))
    run.start("pastview", with_python(pastview_argv()))
    if command_exists("mediaserver"):  # live video (docs/video.md)
        run.start("media", [PY, MANAGE, "mediaserver"])
    for name, queue, concurrency in WORKERS:
        run.start(name, with_python(worker_argv(f"{name}@%h", queue=queue, loglevel="info",
                                                pool="prefork", concurrency=concurrency)))  # fmt: skip
    run.start("beat", with_python(beat_argv(data_dir / "celerybeat-schedule")))
    if drones > 0:
        if command_exists("run_simulated_drones"):
            run.start("drones", [PY, MANAGE, "run_simulated_drones", str(drones)])
        else:
            print("DRONES was given but simulated drones are not available in this version")


def with_python(argv: list[str]) -> list[str]:
    """The command run by the checkout's virtualenv Python (this script may run on another)."""
    return [PY, *argv[1:]]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--drones", type=int, default=int(os.environ.get("DRONES", "0")))
    parser.add_argument("--web-port", type=int, default=int(os.environ.get("WEB_PORT", "8000")))
    parser.add_argument("--profile", choices=("run", "test"), default="run")
    parser.add_argument("--data-dir", type=Path, default=ROOT / ".data" / "run")
    args = parser.parse_args()
    started_services, env = prepare(args.web_port, args.profile)
    run = Foreground(env, args.data_dir / "logs")
    stop = StopSignal().install()
    start_platform(run, args.web_port, args.drones, args.data_dir)
    try:
        while not (stop.wait(0.2) or run.stopping.is_set()):
            pass
    finally:
        print("stopping…", flush=True)
        run.stop()
        if started_services:
            subprocess.run([str(ROOT / "scripts" / "services.sh"), "stop", "run"])
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Run the whole platform in the foreground with prefixed logs (what `make run` ends in).

Starts the project's services if they are not running, migrates, creates the demo account,
then web (ASGI), the MQTT gateway, telemetry ingest, a Celery worker and beat, and
optionally N simulated drones. Ctrl-C stops everything this script started, and nothing
else.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PY = str(ROOT / ".venv" / "bin" / "python")
COLOURS = ["36", "33", "35", "32", "34", "31", "96", "93"]


def command_exists(name: str) -> bool:
    return any(ROOT.glob(f"*/management/commands/{name}.py"))


def services_down() -> bool:
    out = subprocess.run(
        [str(ROOT / "scripts" / "services.sh"), "status", "run"],
        capture_output=True,
        text=True,
    ).stdout
    return "down" in out


class Supervisor:
    def __init__(self) -> None:
        self.procs: list[tuple[str, subprocess.Popen]] = []
        self.stopping = threading.Event()
        self.width = 8

    def start(self, name: str, argv: list[str], env: dict[str, str]) -> None:
        colour = COLOURS[len(self.procs) % len(COLOURS)]
        proc = subprocess.Popen(
            argv,
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,  # its own process group, so Ctrl-C reaches us only
            text=True,
            bufsize=1,
        )
        self.procs.append((name, proc))
        prefix = (
            f"\033[{colour}m{name:<{self.width}}|\033[0m "
            if sys.stdout.isatty()
            else f"{name:<{self.width}}| "
        )
        threading.Thread(target=self._pump, args=(name, proc, prefix), daemon=True).start()

    def _pump(self, name: str, proc: subprocess.Popen, prefix: str) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            sys.stdout.write(prefix + line)
            sys.stdout.flush()
        code = proc.wait()
        if not self.stopping.is_set():
            sys.stdout.write(f"{prefix}exited with code {code}; stopping everything\n")
            self.stopping.set()

    def stop(self) -> None:
        self.stopping.set()
        # SIGTERM to each leader only: Celery and uvicorn stop their own children cleanly.
        for _name, proc in self.procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + 15
        for _name, proc in self.procs:
            try:
                proc.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
            try:  # and nothing of its group outlives it
                os.killpg(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--drones", type=int, default=int(os.environ.get("DRONES", "0")))
    parser.add_argument("--web-port", type=int, default=int(os.environ.get("WEB_PORT", "8000")))
    args = parser.parse_args()

    started_services = services_down()
    if started_services:
        subprocess.run([str(ROOT / "scripts" / "services.sh"), "start", "run"], check=True)
    env = dict(os.environ, DJANGO_SETTINGS_MODULE="config.settings.local", PYTHONUNBUFFERED="1")
    manage = [PY, str(ROOT / "manage.py")]
    subprocess.run([*manage, "migrate", "--noinput", "-v", "0"], check=True, env=env)
    subprocess.run(
        [*manage, "bootstrap_demo", "--url", f"http://127.0.0.1:{args.web_port}/"],
        check=True,
        env=env,
    )

    sup = Supervisor()
    signal.signal(signal.SIGINT, lambda *_: sup.stopping.set())
    signal.signal(signal.SIGTERM, lambda *_: sup.stopping.set())
    sup.start(
        "web",
        [
            PY,
            "-m",
            "uvicorn",
            "config.asgi:application",
            "--host",
            "127.0.0.1",
            "--port",
            str(args.web_port),
            "--no-access-log",
        ],
        env,
    )
    if command_exists("gateway"):
        sup.start("gateway", [*manage, "gateway"], env)
    if command_exists("ingest_telemetry"):
        sup.start("ingest", [*manage, "ingest_telemetry"], env)
    sup.start("pastview", [*manage, "pastview"], env)  # pastview: one level deeper
    sup.start(
        "worker",
        [
            PY,
            "-m",
            "celery",
            "-A",
            "config",
            "worker",
            "-l",
            "info",
            "--concurrency",
            "2",
            "-n",
            "worker@%h",
        ],
        env,
    )
    schedule = ROOT / ".data" / "run" / "celerybeat-schedule"
    sup.start(
        "beat",
        [PY, "-m", "celery", "-A", "config", "beat", "-l", "info", "--schedule", str(schedule)],
        env,
    )
    if args.drones > 0:
        if command_exists("run_simulated_drones"):
            sup.start("drones", [*manage, "run_simulated_drones", str(args.drones)], env)
        else:
            print("DRONES was given but simulated drones are not available in this version")
    try:
        while not sup.stopping.is_set():
            time.sleep(0.2)
    finally:
        print("stopping…", flush=True)
        sup.stop()
        if started_services:
            subprocess.run([str(ROOT / "scripts" / "services.sh"), "stop", "run"])
    return 0


if __name__ == "__main__":
    sys.exit(main())

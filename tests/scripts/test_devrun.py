"""`make run` dies whole: its supervisor (scripts/devrun.py) killed with SIGKILL, which
it cannot handle, leaves none of the processes it started behind."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from django.db import connection

from runtime.processes import Supervised, free_port, port_open, python_env, wait_for
from scripts.devrun import STOP_GRACE_S
from scripts.reaper import GRACE_S, living_groups
from tests.support.outage import REDIS_SERVER

ROOT = Path(__file__).resolve().parents[2]
# web, gateway, ingest, pastview, the media server, the safety, logs and default workers, beat.
PROCESSES = 9
# Measured on the 2-core test machine after the supervisor's SIGKILL: web, gateway,
# ingest, pastview and beat gone within 0.2 s (one poll) of the reaper's SIGTERM; the
# three Celery workers, their output pipe gone with the supervisor, do not finish a warm
# shutdown and go at the reaper's SIGKILL: all gone at 10.2-10.3 s (GRACE_S = 10) with
# Redis up, 3.3 s with Redis stopped; with three busy loops beside other test runs (load
# average 12-16), 10.2-10.6 s and 6.0-10.2 s. The bound is GRACE_S with 10 s of room for
# a loaded machine.
GONE_WITHIN_S = GRACE_S + 10
# Each step of the start (all started, web serving, the safety worker ready) is awaited
# this long. Measured on the 2-core test machine with three busy loops beside other test
# runs (load average 12-16): the safety worker ready 18.0-21.8 s after the supervisor
# started; the nine processes take 20-24 s of CPU between them to start.
STARTED_WITHIN_S = 60.0

pytestmark = pytest.mark.django_db(transaction=True)


class Supervisor:
    """scripts/devrun.py on the test profile, its terminal read line by line."""

    def __init__(self, data_dir: Path, redis_url: str) -> None:
        self.port = free_port()
        env = python_env(TEST_WORKER_DB_NAME=connection.settings_dict["NAME"])
        env |= {"REDIS_URL": redis_url, "CELERY_BROKER_URL": redis_url}
        env["CELERY_RESULT_BACKEND"] = redis_url
        # The media server's own ports: on its defaults (8890, 8891) a second run on the
        # machine (this file's other tests on another xdist worker, a developer's `make
        # run`) fails to bind, exits, and its supervisor stops everything it started.
        env["LIVE_VIDEO_PORT"], env["LIVE_VIDEO_DRONE_PORT"] = str(free_port()), str(free_port())
        argv = [sys.executable, str(ROOT / "scripts" / "devrun.py"), "--profile", "test"]
        argv += ["--web-port", str(self.port), "--drones", "0", "--data-dir", str(data_dir)]
        self.started_at = time.monotonic()
        self.process = subprocess.Popen(
            argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        self.lines: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line)

    def exited(self) -> bool:
        """Whether a process it started ended on its own (then it stops them all)."""
        return "exited with code" in "".join(self.lines)

    def until(self, predicate: Callable[[], bool], timeout: float = STARTED_WITHIN_S) -> bool:
        """Wait for `predicate`; give up at once when a process ended on its own."""
        return bool(wait_for(lambda: predicate() or self.exited(), timeout) and not self.exited())

    def groups(self) -> set[int]:
        """The process group of each process it said it started (each leads its own)."""
        return {int(pid) for pid in re.findall(r"started \(pid (\d+)\)", "".join(self.lines))}

    def kill(self) -> None:
        os.kill(self.process.pid, signal.SIGKILL)
        self.process.wait(10)


def survivors(groups: set[int]) -> list[str]:
    """Each process left in `groups`: pid, state, process group and command line."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
            argv = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue  # ended while we looked
        fields = text[text.rindex(")") + 2 :].split()
        if int(fields[2]) in groups:
            found.append(f"{stat.parent.name} {fields[0]} pgrp={fields[2]} {argv.strip()}")
    return found


@pytest.fixture
def redis(tmp_path):  # type: ignore[no-untyped-def]
    """A Redis of the test's own, which it may stop."""
    port = free_port()
    argv = [REDIS_SERVER, "--port", str(port), "--bind", "127.0.0.1", "--save", ""]
    server = Supervised("redis", argv, log_path=tmp_path / "redis.log", port=port)
    server.start().wait_ready(20)
    yield server
    server.stop()


@pytest.mark.parametrize("redis_gone", [False, True], ids=["services-up", "redis-stopped"])
def test_killing_the_supervisor_leaves_none_of_its_processes_running(tmp_path, redis, redis_gone):
    supervisor = Supervisor(tmp_path, f"redis://127.0.0.1:{redis.port}/0")
    try:
        assert supervisor.until(lambda: len(supervisor.groups()) == PROCESSES), supervisor.lines
        assert supervisor.until(lambda: port_open(supervisor.port)), supervisor.lines
        safety_log = tmp_path / "logs" / "safety.log"
        assert supervisor.until(lambda: "ready." in safety_log.read_text()), supervisor.lines
        print(f"the safety worker ready {time.monotonic() - supervisor.started_at:.1f} s in")
        groups = supervisor.groups()
        assert living_groups(groups) == groups, supervisor.lines  # all up, none exited
        if redis_gone:
            redis.stop()
            time.sleep(1)  # the workers notice, and retry the connection
        supervisor.kill()
        killed_at = time.monotonic()
        assert wait_for(lambda: not living_groups(groups), GONE_WITHIN_S, 0.2), survivors(groups)
        print(f"every process gone {time.monotonic() - killed_at:.1f} s after the SIGKILL")
    finally:
        if supervisor.process.poll() is None:
            supervisor.kill()
        for group in living_groups(supervisor.groups()):
            os.killpg(group, signal.SIGKILL)  # a failed test leaves nothing running either


def test_ctrl_c_stops_every_process_and_the_supervisor_with_them(tmp_path, redis):
    supervisor = Supervisor(tmp_path, f"redis://127.0.0.1:{redis.port}/0")
    try:
        assert supervisor.until(lambda: len(supervisor.groups()) == PROCESSES), supervisor.lines
        assert supervisor.until(lambda: port_open(supervisor.port)), supervisor.lines
        groups = supervisor.groups()
        supervisor.process.send_signal(signal.SIGINT)
        assert supervisor.process.wait(STOP_GRACE_S + 10) == 0
        assert not living_groups(groups)
        assert "exited with code" not in "".join(supervisor.lines)  # none died on its own
    finally:
        if supervisor.process.poll() is None:
            supervisor.kill()
        for group in living_groups(supervisor.groups()):
            os.killpg(group, signal.SIGKILL)

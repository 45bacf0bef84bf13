"""scripts/cpu_weights.sh, which `make test` runs the real-time tests under: two groups of
the kernel's `cpu` controller, `realtime` at ten times the weight of `others`, that keep
every descendant of a process that joins, whatever session it makes for itself."""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from runtime.processes import wait_for

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = str(ROOT / "scripts" / "cpu_weights.sh")
ROOTS = {"v1": Path("/sys/fs/cgroup/cpu"), "v2": Path("/sys/fs/cgroup")}


def weights(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([SCRIPT, *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def handle() -> Iterator[str]:
    made = weights("make", str(os.getpid()))
    if made.returncode != 0:
        pytest.skip(
            "no write access to the kernel's cpu controller here (make test then runs the real-time tests after the others)"
        )
    handle = made.stdout.strip()
    yield handle
    weights("remove", handle)


def group_dir(handle: str, group: str) -> Path:
    version, name = handle.split(":", 1)
    return ROOTS[version] / f"{name}-{group}"


def members(handle: str, group: str) -> set[int]:
    return {int(pid) for pid in (group_dir(handle, group) / "cgroup.procs").read_text().split()}


def test_realtime_weighs_ten_times_others(handle):
    version = handle.split(":", 1)[0]
    setting = "cpu.shares" if version == "v1" else "cpu.weight"
    realtime = int((group_dir(handle, "realtime") / setting).read_text())
    others = int((group_dir(handle, "others") / setting).read_text())
    assert realtime == 10 * others


def test_a_joined_shell_and_the_sessions_its_children_make_stay_in_the_group(handle):
    # The ground processes a test starts each make a session of their own.
    shell = subprocess.Popen(
        ["bash", "-c", f'{SCRIPT} join "$1" realtime && {{ setsid sleep 30 & wait; }}', "-", handle]
    )
    try:
        assert wait_for(lambda: len(members(handle, "realtime")) == 2, 10)
        child = (members(handle, "realtime") - {shell.pid}).pop()
        assert os.getsid(child) == child  # a session of its own, still in the group
        assert members(handle, "others") == set()
    finally:
        for pid in members(handle, "realtime"):
            os.kill(pid, 9)
        shell.wait()


def test_remove_moves_what_is_left_to_the_root_group_and_removes_both(handle):
    sleeper = subprocess.Popen(
        ["bash", "-c", f'{SCRIPT} join "$1" others && exec sleep 30', "-", handle]
    )
    try:
        assert wait_for(lambda: members(handle, "others") == {sleeper.pid}, 10)
        assert weights("remove", handle).returncode == 0
        assert not group_dir(handle, "others").exists()
        assert not group_dir(handle, "realtime").exists()
        assert sleeper.poll() is None  # moved, not ended
    finally:
        sleeper.kill()
        sleeper.wait()


def test_a_new_run_removes_the_empty_groups_of_runs_that_are_gone(handle):
    gone = subprocess.Popen(["true"])
    gone.wait()  # a process id nobody holds now
    root = group_dir(handle, "others").parent
    stale = root / f"skyhive-test-{gone.pid}-{time.time_ns()}-others"
    alive = root / f"skyhive-test-{os.getpid()}-{time.time_ns()}-others"
    stale.mkdir()
    alive.mkdir()
    try:
        other = weights("make", str(os.getpid())).stdout.strip()
        weights("remove", other)
        assert not stale.exists()
        assert alive.exists()  # its run is still going
    finally:
        for directory in (stale, alive):
            if directory.exists():
                directory.rmdir()

#!/usr/bin/env python
"""Ends what `make run` started once its supervisor (scripts/devrun.py) is gone, however
it went: Ctrl-C, an exception, or SIGKILL, which no handler of its own can catch.

The supervisor starts this process first, in a session of its own (so the signal that
ends the supervisor's terminal group does not end it), and writes on its stdin the
process group of each process it starts, one number a line. The pipe's write end is the
supervisor's alone (its other children do not inherit it), so the end of the input is the
end of the supervisor, whatever ended it. Then every group written gets SIGTERM (each
process drains on it), and SIGKILL after GRACE_S for whatever is left, so nothing of
theirs outlives the supervisor by more than GRACE_S plus one poll.

A group is watched, not a process: a Celery worker's pool, uvicorn's children and the
simulated drones' boards and agents share their leader's group (runtime.processes
Supervised starts each leader in one of its own).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Iterable
from pathlib import Path

# A Celery worker may not finish its warm shutdown on SIGTERM (seen for over 15 s with
# Redis stopped, and with its output pipe gone with the supervisor): drained work is the
# rule, but not for ever. Its tasks are acknowledged late, so a kill loses none.
GRACE_S = 10.0
POLL_S = 0.1


def living_groups(groups: set[int]) -> set[int]:
    """Those of `groups` with a process in them that is not a zombie (a zombie's group
    still answers kill(0), yet it runs nothing: its parent just has not reaped it)."""
    alive: set[int] = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue  # ended while we looked
        # "pid (comm) state ppid pgrp ...": comm may hold spaces and parentheses.
        fields = text[text.rindex(")") + 2 :].split()
        if int(fields[2]) in groups and fields[0] != "Z":
            alive.add(int(fields[2]))
    return alive


def signal_groups(groups: Iterable[int], sig: int) -> None:
    for group in groups:
        try:
            os.killpg(group, sig)
        except (ProcessLookupError, PermissionError):
            pass


def end_groups(groups: set[int], grace_s: float = GRACE_S) -> set[int]:
    """SIGTERM to every group, SIGKILL to what is left after `grace_s`; what survived."""
    signal_groups(living_groups(groups), signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    while living_groups(groups) and time.monotonic() < deadline:
        time.sleep(POLL_S)
    signal_groups(living_groups(groups), signal.SIGKILL)
    deadline = time.monotonic() + 5
    while living_groups(groups) and time.monotonic() < deadline:
        time.sleep(POLL_S)
    return living_groups(groups)


def main() -> int:
    # Only the end of the input ends us: a terminal's Ctrl-C or hang-up is the
    # supervisor's to handle, and we must outlive it to do our work.
    for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    groups: set[int] = set()
    for line in sys.stdin:
        if line.strip().isdigit() and int(line) > 1:
            groups.add(int(line))
    left = end_groups(groups)
    return 1 if left else 0


if __name__ == "__main__":
    sys.exit(main())

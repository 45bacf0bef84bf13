"""A real `celery worker` subprocess on the test database, for tests and benchmarks.

The worker reads the database pytest-django created (TEST_WORKER_DB_NAME, see
config/settings/test.py). Callers that share the test Redis with other runs give it a
queue of their own, so it never takes their tasks.
"""

from __future__ import annotations

import os
import subprocess
import sys
from typing import IO

from .paths import ROOT

# Worker-to-worker chatter the tests never read; without it a worker starts faster.
NO_CHATTER = ("--without-heartbeat", "--without-gossip", "--without-mingle")


def worker_env(database_name: str, **extra: str) -> dict[str, str]:
    """This process's environment with the test settings, pointed at `database_name`."""
    return dict(
        os.environ,
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=database_name,
        **extra,
    )


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


def start_worker(
    name: str,
    env: dict[str, str],
    *,
    output: IO | int | None = None,
    queue: str | None = None,
    loglevel: str = "warning",
    chatter: bool = True,
) -> subprocess.Popen:
    """Start a solo-pool worker from the project root; stdout and stderr go to `output`
    (a file, or subprocess.DEVNULL), or stay this process's when it is None."""
    return subprocess.Popen(
        worker_argv(name, queue=queue, loglevel=loglevel, chatter=chatter),
        cwd=ROOT,
        env=env,
        stdout=output,
        stderr=None if output is None else subprocess.STDOUT,
    )

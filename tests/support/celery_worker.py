"""A real `celery worker` subprocess on the test database, for tests and benchmarks.

The worker reads the database pytest-django created (TEST_WORKER_DB_NAME, see
config/settings/test.py). Callers that share the test Redis with other runs give it a
queue of their own, so it never takes their tasks.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import IO, Any

from runtime.processes import Supervised
from workers.ground import worker_argv

from .paths import ROOT


def worker_env(database_name: str, **extra: str) -> dict[str, str]:
    """This process's environment with the test settings, pointed at `database_name`."""
    return dict(
        os.environ,
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=database_name,
        **extra,
    )


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


# Celery's line, at log level info, once the worker consumes from its queues.
READY_TEXT = " ready."


def consuming_worker(
    name: str,
    env: dict[str, str],
    log_path: Path,
    *,
    queue: str,
    timeout: float = 60.0,
    **argv: Any,
) -> Supervised:
    """A worker (`worker_argv`'s options in `argv`, info-level log at `log_path`) that
    consumes from `queue` before this returns, so that a test's time bound never includes
    the worker's own start (seconds of imports, more on a loaded machine). It runs in a
    process group of its own: `stop()` leaves none of its pool behind."""
    worker = Supervised(
        name,
        worker_argv(f"{name}@%h", queue=queue, loglevel="info", chatter=False, **argv),
        env,
        log_path,
        ready_text=(READY_TEXT,),
    )
    return worker.start().wait_ready(timeout)

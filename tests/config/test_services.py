"""Celery and settings, on the real services started for the suite."""

import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from runtime.processes import stop_process
from tests.support.celery_worker import start_worker, worker_env

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.django_db(transaction=True)
def test_a_real_celery_worker_runs_a_task():
    # The worker must use the test database that pytest-django created.
    from django.db import connection

    from workers.tasks import ping

    env = worker_env(connection.settings_dict["NAME"])
    worker = start_worker(f"test-{uuid.uuid4().hex[:6]}@%h", env)
    try:
        token = uuid.uuid4().hex
        result = ping.delay(token)
        assert result.get(timeout=30)["pong"] == token
    finally:
        stop_process(worker)


def test_deploy_checks_pass_with_production_values():
    env = dict(
        os.environ,
        DJANGO_SETTINGS_MODULE="config.settings.production",
        SECRET_KEY="x" * 20 + uuid.uuid4().hex + "y" * 20,
        ALLOWED_HOSTS="drones.example.org",
        DEBUG="false",
    )
    env.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)  # set by the browser tests' fixture
    started = time.monotonic()
    out = subprocess.run(
        [sys.executable, "manage.py", "check", "--deploy", "--fail-level", "WARNING"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    # Measured 2.0 s quiet and 5.9 s with four busy processes on two cores.
    assert time.monotonic() - started < 60

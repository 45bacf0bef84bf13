"""For the log API and page tests: a real Celery worker on its own queue, a private logs folder, and upload helpers.

The worker listens only on a queue named for this run, so workers started by other test
folders (or other runs sharing the test Redis) never take our imports, and ours never
takes theirs.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import pytest

from tests.support.celery_worker import consuming_worker, worker_env

QUEUE = f"logs-test-{uuid.uuid4().hex[:8]}"


@pytest.fixture(scope="session")
def logs_dir(tmp_path_factory) -> Path:  # type: ignore[no-untyped-def]
    return tmp_path_factory.mktemp("flight-logs")


@pytest.fixture
def logs_settings(settings, logs_dir):  # type: ignore[no-untyped-def]
    """Imports go to our worker's queue and folder; the API and page tests use it."""
    settings.LOGS_DIR = str(logs_dir)
    settings.LOGS_IMPORT_QUEUE = QUEUE


@pytest.fixture(scope="session")
def worker(request, logs_dir):  # type: ignore[no-untyped-def]
    """One `celery worker --pool solo` for the folder, reading the test database."""
    request.getfixturevalue("django_db_setup")
    from django.db import connection

    env = worker_env(
        connection.settings_dict["NAME"],
        LOGS_DIR=str(logs_dir),
        LOGS_IMPORT_QUEUE=QUEUE,
        PYTHONUNBUFFERED="1",
    )
    started = consuming_worker(QUEUE, env, logs_dir / f"worker-{QUEUE}.log", queue=QUEUE)
    yield started
    started.stop()


@pytest.fixture(scope="session")
def live_logs(request, logs_dir):  # type: ignore[no-untyped-def]
    """The real ASGI app under uvicorn, sending imports to our worker's queue."""
    request.getfixturevalue("django_db_setup")
    from django.db import connection

    from tests.support.live import LiveServer

    server = LiveServer(
        connection.settings_dict["NAME"],
        extra_env={"LOGS_DIR": str(logs_dir), "LOGS_IMPORT_QUEUE": QUEUE},
    )
    yield server
    server.stop()


def upload(client, path: Path, **extra: object):  # type: ignore[no-untyped-def]
    with open(path, "rb") as f:
        return client.post("/api/v1/logs/", {"file": f, **extra})


def wait_until_processed(client, log_id: str, timeout: float = 60.0) -> dict:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while True:
        body = client.get(f"/api/v1/logs/{log_id}/").json()
        if body["status"] != "processing" or time.monotonic() > deadline:
            return body
        time.sleep(0.1)

"""Celery routing by urgency: safety work and log imports each on their own queue."""

from __future__ import annotations

import os
import subprocess
import sys
import uuid

import pytest
import redis

from config.queues import queue_for, route_task
from tests.support.paths import ROOT


def test_every_safety_task_and_the_import_go_to_their_queue(settings):
    settings.SAFETY_TASK_QUEUE = "safety"
    settings.LOGS_IMPORT_QUEUE = "logs"
    from config.celery import app

    app.loader.import_default_modules()
    for name in settings.SAFETY_TASKS:
        assert name in app.tasks, f"{name} is routed but no such task exists"
        assert queue_for(name) == "safety"
    assert route_task("missions.replace_drone", (), {}, {}) == {"queue": "safety"}
    assert route_task("logs.import", (), {}, {}) == {"queue": "logs"}
    # Everything else: the default queue.
    assert route_task("telemetry.maintain_partitions", (), {}, {}) is None
    assert route_task("logs.sweep_stuck", (), {}, {}) is None


def test_an_empty_queue_name_sends_that_class_to_the_default_queue(settings):
    settings.SAFETY_TASK_QUEUE = ""
    assert route_task("missions.replace_drone", (), {}, {}) is None


def test_the_settings_route_safety_work_and_imports_away_from_the_default_queue():
    """What `make run` and production get when the environment names no queue."""
    env = {
        k: v for k, v in os.environ.items() if k not in ("SAFETY_TASK_QUEUE", "LOGS_IMPORT_QUEUE")
    }
    env["DJANGO_SETTINGS_MODULE"] = "config.settings.local"
    code = (
        "import django; django.setup(); from django.conf import settings; "
        "print(settings.SAFETY_TASK_QUEUE, settings.LOGS_IMPORT_QUEUE, settings.CELERY_TASK_ROUTES)"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                         text=True, check=True).stdout.split(" ", 2)  # fmt: skip
    assert out[:2] == ["safety", "logs"]
    assert "config.queues.route_task" in out[2]


@pytest.mark.django_db
def test_a_queued_safety_task_lands_on_the_safety_queue_in_redis(settings):
    from config.celery import app
    from fleet.tasks import sweep_offline_drones
    from missions.tasks import replace_offline

    queue = f"safety-{uuid.uuid4().hex[:8]}"
    settings.SAFETY_TASK_QUEUE = queue
    broker = redis.Redis.from_url(str(app.conf.broker_url))
    try:
        sweep_offline_drones.delay()
        replace_offline.delay("m", "a", 1)
        assert broker.llen(queue) == 2
    finally:
        broker.delete(queue)

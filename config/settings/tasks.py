"""Celery: reliability, queues by urgency, and every periodic task with its interval (each
interval is stated with its concern)."""

from __future__ import annotations

from config.env import env

from .airspace import AIRSPACE_LANDING_INTERVAL_S, AIRSPACE_LIVE_INTERVAL_S
from .core import REDIS_URL
from .fleet import OFFLINE_SWEEP_INTERVAL_S
from .livevideo import LIVE_VIDEO_PRUNE_INTERVAL_S
from .logs import LOGS_SWEEP_INTERVAL_S
from .maintenance import MAINTENANCE_WARN_INTERVAL_S
from .missions import MISSIONS_RESUME_INTERVAL_S
from .records import RECORDS_SETTLE_INTERVAL_S

CELERY_BROKER_URL = env.str("CELERY_BROKER_URL", REDIS_URL)
CELERY_RESULT_BACKEND = env.str("CELERY_RESULT_BACKEND", REDIS_URL)
CELERY_TASK_SERIALIZER = "json"
CELERY_RESULT_SERIALIZER = "json"
CELERY_ACCEPT_CONTENT = ["json"]
CELERY_RESULT_EXPIRES = 3600
# Reliability: a task is acknowledged only after it ran (acks late), and one
# whose worker process died is put back (reject on worker lost), so a worker killed
# mid-task loses nothing; every task is idempotent, so a rerun changes nothing twice.
CELERY_TASK_ACKS_LATE = True
CELERY_TASK_REJECT_ON_WORKER_LOST = True
CELERY_WORKER_PREFETCH_MULTIPLIER = 1
CELERY_TASK_TIME_LIMIT = env.int("CELERY_TASK_TIME_LIMIT", 30 * 60)
CELERY_TASK_SOFT_TIME_LIMIT = env.int("CELERY_TASK_SOFT_TIME_LIMIT", 25 * 60)
# When the whole worker dies, Redis has no broker-side redelivery: the message waits in
# the unacknowledged set until it is older than the visibility timeout, then any worker
# puts it back (config/celery.py checks often). It must exceed the longest task
# (CELERY_TASK_TIME_LIMIT) or a slow task would run twice; tests set a short one.
CELERY_BROKER_TRANSPORT_OPTIONS = {
    "visibility_timeout": env.float("CELERY_VISIBILITY_TIMEOUT", 3600.0),
}
# Keep retrying the broker for ever (Celery stops after 100 attempts by default): a Redis
# restart must not end the worker.
CELERY_BROKER_CONNECTION_RETRY_ON_STARTUP = True
CELERY_BROKER_CONNECTION_MAX_RETRIES = None

# Replicated deployments (and test runs sharing one Redis) may name their own queue. Only
# when asked: a configured default queue can no longer be changed on `app.conf` at run
# time, which the end-to-end tests with an in-process gateway do.
if env.str("CELERY_TASK_DEFAULT_QUEUE", ""):
    CELERY_TASK_DEFAULT_QUEUE = env.str("CELERY_TASK_DEFAULT_QUEUE", "celery")
# Queues by urgency (config/queues.py routes; docs/scaling.md lists who serves them).
# Work that keeps drones safe (replacing a failing drone, bringing in helpers, handling a
# drone gone offline, relieving a panic station) has a queue and workers of its own, so
# it never waits behind a log import or any other slow task. Empty: the default queue.
SAFETY_TASK_QUEUE = env.str("SAFETY_TASK_QUEUE", "safety")
SAFETY_TASKS = [
    "missions.replace_drone",
    "missions.collaborate",
    "missions.replace_offline",
    "missions.resume_paused",
    "missions.relieve_panic_stations",
    "fleet.sweep_offline",
    "airspace.watch_separation",
    "airspace.advance_landings",
]
CELERY_TASK_ROUTES = ["config.queues.route_task"]


def _every(task: str, seconds: float) -> dict:
    """A periodic task that expires when its next run is due, so a busy worker never
    runs a backlog of stale ones."""
    return {"task": task, "schedule": seconds, "options": {"expires": seconds}}


CELERY_BEAT_SCHEDULE = {
    "telemetry-maintain-partitions": {"task": "telemetry.maintain_partitions", "schedule": 3600.0},
    "fleet.sweep_offline": _every("fleet.sweep_offline", OFFLINE_SWEEP_INTERVAL_S),
    "missions.resume_paused": _every("missions.resume_paused", MISSIONS_RESUME_INTERVAL_S),
    "missions.relieve_panic_stations": _every(
        "missions.relieve_panic_stations", MISSIONS_RESUME_INTERVAL_S
    ),
    "logs.sweep_stuck": _every("logs.sweep_stuck", LOGS_SWEEP_INTERVAL_S),
    "records.settle": _every("records.settle", RECORDS_SETTLE_INTERVAL_S),
    "livevideo.prune_recordings": _every("livevideo.prune_recordings", LIVE_VIDEO_PRUNE_INTERVAL_S),
    "maintenance.warn": _every("maintenance.warn", MAINTENANCE_WARN_INTERVAL_S),
    "airspace.watch_separation": _every("airspace.watch_separation", AIRSPACE_LIVE_INTERVAL_S),
    "airspace.advance_landings": _every("airspace.advance_landings", AIRSPACE_LANDING_INTERVAL_S),
}

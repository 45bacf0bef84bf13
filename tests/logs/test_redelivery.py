"""Log imports on a queue of their own with a redelivery limit, safety work on another,
and the sweep of logs left processing by a worker that is gone.

Real Redis and real `celery worker` processes (prefork: the pool notices a child that
died and Celery delivers its message again at once), on the test database.
"""

from __future__ import annotations

import shutil
import time
import uuid
from datetime import timedelta
from pathlib import Path
from types import SimpleNamespace

import pytest
import redis
from django.utils import timezone

from logs import attempts, services
from logs.models import FlightLog, LogStatus
from logs.uploads import StoredUpload
from runtime.processes import Supervised, wait_for
from tests.missions.conftest import online_drone, outbox, point_at  # noqa: F401 - a fixture
from tests.support.celery_worker import consuming_worker, worker_env

pytestmark = pytest.mark.django_db(transaction=True)

ULOG = Path(__file__).resolve().parents[1] / "data" / "ulog" / "sample_log_small.ulg"
LIMIT = 3
# Each doomed import looks busy this long before it kills its worker process.
CRASH_AFTER_S = 3.0


def _upload(org, logs_dir: Path, name: str = "flight.ulg") -> FlightLog:  # type: ignore[no-untyped-def]
    """A log as the upload API stores it; its import is queued on commit (autocommit here)."""
    incoming = logs_dir / "incoming"
    incoming.mkdir(parents=True, exist_ok=True)
    path = incoming / f"{uuid.uuid4().hex}.ulg"
    shutil.copyfile(ULOG, path)
    upload = StoredUpload(path, name, path.stat().st_size, None)
    return services.create_log(organisation=org, owner=None, upload=upload)


def _start_worker(name: str, queue: str, directory: Path, env: dict[str, str]) -> Supervised:
    log_path = directory / f"{name}.log"
    return consuming_worker(
        name, env, log_path, queue=queue, timeout=90, pool="prefork", concurrency=1
    )


@pytest.fixture
def queues(request, settings, outbox, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    """Safety and log queues of this test only, and a worker process serving each; with
    the parameter True, one queue and one worker for both (the layout without urgency)."""
    from django.db import connection

    from config.celery import app

    tag = uuid.uuid4().hex[:8]
    shared = getattr(request, "param", False)
    names = SimpleNamespace(safety=f"{'logs' if shared else 'safety'}-{tag}", logs=f"logs-{tag}")
    settings.SAFETY_TASK_QUEUE = names.safety
    settings.LOGS_IMPORT_QUEUE = names.logs
    settings.LOGS_DIR = str(tmp_path / "logs")
    settings.LOGS_IMPORT_REDELIVERY_LIMIT = LIMIT
    env = worker_env(
        connection.settings_dict["NAME"],
        REDIS_URL=settings.REDIS_URL,  # the outbox fixture's database
        CELERY_BROKER_URL=str(app.conf.broker_url),
        CELERY_RESULT_BACKEND=str(app.conf.result_backend),
        LOGS_DIR=settings.LOGS_DIR,
        LOGS_IMPORT_REDELIVERY_LIMIT=str(LIMIT),
        PYTHONUNBUFFERED="1",
    )
    crashing = dict(
        env,
        LOGS_IMPORT_FUNCTION="tests.support.crashing_import.import_to_store",
        CRASH_AFTER_S=str(CRASH_AFTER_S),
    )
    names.logs_worker = _start_worker(f"logs-{tag}", names.logs, tmp_path, crashing)
    names.safety_worker = (
        names.logs_worker if shared else _start_worker(f"safety-{tag}", names.safety, tmp_path, env)
    )
    yield names
    for worker in {id(w): w for w in (names.logs_worker, names.safety_worker)}.values():
        worker.stop()
    redis.Redis.from_url(str(app.conf.broker_url)).delete(names.safety, names.logs)


def _mission_with_a_critical_alarm(org):  # type: ignore[no-untyped-def]
    from missions.creation import create_mission
    from missions.models import Event
    from missions.planning import mission_steps
    from missions.startstop import start_mission

    first = online_drone(org, "ACME_A")
    online_drone(org, "ACME_B", north=50)
    steps = mission_steps([point_at(10.0 * i, 0.0) for i in range(3)], altitude=10)
    mission = create_mission(organisation=org, name="survey", steps=steps)
    assignment = start_mission(mission, drone=first).assignment
    alarm = Event.objects.create(
        mission=mission,
        drone=first,
        kind=Event.Kind.ALARM,
        data={"level": "CRITICAL", "position": {"lat": first.lat, "lon": first.lon, "alt": 10.0},
              "received_at": time.time()},
    )  # fmt: skip
    return mission, assignment, alarm


def _replace_during_a_doomed_import(org, queues) -> tuple[FlightLog, float, FlightLog]:  # type: ignore[no-untyped-def]
    """Upload a log whose import kills its worker; once its first attempt runs, queue a
    replacement: (the log, seconds until the replacement ran, the log at that moment)."""
    from django.conf import settings

    from missions.models import Assignment
    from missions.tasks import replace_drone

    mission, assignment, alarm = _mission_with_a_critical_alarm(org)
    log = _upload(org, Path(settings.LOGS_DIR))
    assert wait_for(lambda: FlightLog.objects.get(pk=log.pk).attempts >= 1, 60)
    queued = time.monotonic()
    replace_drone.delay(str(mission.pk), str(assignment.pk), alarm.pk)
    replaced = mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT)
    deadline = (LIMIT + 2) * (CRASH_AFTER_S + 10)
    assert wait_for(replaced.exists, deadline), queues.safety_worker.output()[-3000:]
    latency = time.monotonic() - queued
    assert replaced.get().drone.drone_id == "ACME_B"
    return log, latency, FlightLog.objects.get(pk=log.pk)


@pytest.mark.parametrize("queues", [True], indirect=True)
def test_baseline_on_one_queue_the_replacement_waits_for_every_crash(world_tx, queues):
    """The layout without urgency queues, measured for comparison with the next test."""
    log, latency, _ = _replace_during_a_doomed_import(world_tx.org, queues)
    print(f"baseline, one queue for both: the replacement ran {latency:.2f} s after it was "
          f"queued, behind a log whose {LIMIT} attempts take {CRASH_AFTER_S} s each")  # fmt: skip
    # At least until the running attempt killed its worker (queued just after it began);
    # where a redelivered import goes in the queue decides how many more it waits.
    assert latency > CRASH_AFTER_S / 2
    assert wait_for(
        lambda: FlightLog.objects.get(pk=log.pk).status == LogStatus.FAILED,
        (LIMIT + 2) * (CRASH_AFTER_S + 10),
    )


def test_a_log_that_kills_its_worker_fails_after_the_limit_and_a_replacement_runs_at_once(
    world_tx, queues
):
    log, latency, busy = _replace_during_a_doomed_import(world_tx.org, queues)
    print(f"replacement ran {latency:.2f} s after it was queued, during import attempt "
          f"{busy.attempts} of a log whose every attempt takes {CRASH_AFTER_S} s")  # fmt: skip
    # The log queue was still busy with the doomed import: on its queue, the replacement
    # would have waited for every remaining crash (several times CRASH_AFTER_S).
    assert busy.status == LogStatus.PROCESSING and busy.attempts <= LIMIT
    assert latency < CRASH_AFTER_S

    assert wait_for(
        lambda: FlightLog.objects.get(pk=log.pk).status != LogStatus.PROCESSING,
        (LIMIT + 2) * (CRASH_AFTER_S + 10),
    ), queues.logs_worker.output()[-3000:]
    log.refresh_from_db()
    assert log.status == LogStatus.FAILED
    assert f"stopped its worker {LIMIT} times" in log.error
    assert log.attempts == LIMIT + 1  # the last delivery only recorded the failure
    output = queues.logs_worker.output()
    assert output.count("exited with 'exitcode 70'") == LIMIT, output[-3000:]
    assert queues.logs_worker.alive  # the pool's parent survives; only children died
    # Nothing left for the import on its queue: the message was acknowledged at last.
    from config.celery import app

    assert redis.Redis.from_url(str(app.conf.broker_url)).llen(queues.logs) == 0


def _stuck(org, logs_dir: Path, **fields: object) -> FlightLog:  # type: ignore[no-untyped-def]
    """A processing log as a vanished worker leaves it: no message, no sign of life."""
    log = _upload(org, logs_dir)
    FlightLog.objects.filter(pk=log.pk).update(**fields)
    return FlightLog.objects.get(pk=log.pk)


def test_logs_left_processing_by_a_vanished_worker_are_queued_again_or_failed(
    world_tx, settings, logs_dir, tmp_path
):
    """No worker serves the queue while the logs are made stuck; then the sweep runs, and
    a real worker imports what it queued again."""
    from django.db import connection

    from config.celery import app

    queue = f"logs-sweep-{uuid.uuid4().hex[:8]}"
    settings.LOGS_DIR = str(logs_dir)
    settings.LOGS_IMPORT_QUEUE = queue
    settings.LOGS_STUCK_AFTER_S = 60.0
    settings.LOGS_UNSTARTED_AFTER_S = 300.0
    broker = redis.Redis.from_url(str(app.conf.broker_url))
    long_ago = timezone.now() - timedelta(minutes=10)
    dead = _stuck(world_tx.org, logs_dir, attempts=1, import_task="gone",
                  heartbeat_at=long_ago, queued_at=long_ago)  # fmt: skip
    never_started = _stuck(world_tx.org, logs_dir, queued_at=long_ago)
    # Queued two minutes ago and not started: still waiting its turn, not lost.
    waiting = _stuck(world_tx.org, logs_dir, queued_at=timezone.now() - timedelta(minutes=2))
    hopeless = _stuck(world_tx.org, logs_dir, attempts=LIMIT, import_task="gone",
                      heartbeat_at=long_ago, queued_at=long_ago)  # fmt: skip
    alive = _stuck(world_tx.org, logs_dir, attempts=1, import_task="running",
                   heartbeat_at=timezone.now(), queued_at=long_ago)  # fmt: skip
    broker.delete(queue)  # the uploads' own messages: as if they were lost with the worker

    swept = services.sweep_stuck()
    assert sorted(swept["requeued"]) == sorted([str(dead.pk), str(never_started.pk)])
    assert swept["failed"] == [str(hopeless.pk)]
    assert broker.llen(queue) == 2
    hopeless.refresh_from_db()
    assert hopeless.status == LogStatus.FAILED
    assert f"stopped its worker {LIMIT} times" in hopeless.error
    assert services.sweep_stuck() == {"requeued": [], "failed": []}  # queued just now

    env = worker_env(connection.settings_dict["NAME"], LOGS_DIR=str(logs_dir),
                     CELERY_BROKER_URL=str(app.conf.broker_url), PYTHONUNBUFFERED="1")  # fmt: skip
    worker = _start_worker(f"sweep-{queue}", queue, tmp_path, env)
    try:
        for log in (dead, never_started):
            assert wait_for(
                lambda log=log: FlightLog.objects.get(pk=log.pk).status != LogStatus.PROCESSING, 60
            ), worker.output()[-3000:]
            log.refresh_from_db()
            assert log.status == LogStatus.READY, log.error
        assert dead.attempts == 2 and never_started.attempts == 1
        for untouched in (alive, waiting):
            untouched.refresh_from_db()
            assert untouched.status == LogStatus.PROCESSING
        assert alive.attempts == 1 and waiting.attempts == 0
    finally:
        worker.stop()
        broker.delete(queue)


def test_a_delivery_takes_a_log_only_from_no_one_itself_or_a_silent_holder(
    world_tx, settings, logs_dir
):
    settings.LOGS_DIR = str(logs_dir)
    settings.LOGS_IMPORT_QUEUE = f"logs-unused-{uuid.uuid4().hex[:8]}"
    settings.LOGS_IMPORT_REDELIVERY_LIMIT = LIMIT
    log = _upload(world_tx.org, logs_dir)
    assert attempts.claim(str(log.pk), "first") == 1
    assert attempts.claim(str(log.pk), "second") is None  # "first" is alive
    assert attempts.claim(str(log.pk), "first") == 2  # its own redelivery
    FlightLog.objects.filter(pk=log.pk).update(
        heartbeat_at=timezone.now() - timedelta(seconds=settings.LOGS_STUCK_AFTER_S + 1)
    )
    assert attempts.claim(str(log.pk), "second") == 3
    assert not attempts.over_limit(3) and attempts.over_limit(4)
    FlightLog.objects.filter(pk=log.pk).update(status=LogStatus.READY)
    assert attempts.claim(str(log.pk), "second") is None
    redis.Redis.from_url(settings.CELERY_BROKER_URL).delete(settings.LOGS_IMPORT_QUEUE)

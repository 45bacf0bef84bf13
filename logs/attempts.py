"""Import attempts of a log: which delivery runs it, whether it is alive, how often it died.

Celery delivers an import again when its worker process dies (acks late, reject on worker
lost), which a file that crashes its importer would make endless. Each delivery that
starts an import takes the log (a lease in its row) and counts one attempt; a log whose
attempts reached LOGS_IMPORT_REDELIVERY_LIMIT without finishing is failed. A running
import refreshes `heartbeat_at`; a log silent for LOGS_STUCK_AFTER_S is no longer held,
and the sweep queues it again or fails it.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime, timedelta

from django.conf import settings
from django.db import DatabaseError, connections
from django.db.models import F, Q
from django.db.models.functions import Greatest
from django.utils import timezone

from logs.models import FlightLog, LogStatus

logger = logging.getLogger(__name__)


def stale_before() -> datetime:
    return timezone.now() - timedelta(seconds=float(settings.LOGS_STUCK_AFTER_S))


def crash_reason(times: int) -> str:
    return (
        f"The import stopped its worker {times} times, so it was given up; "
        "the file may be corrupt in a way the importer does not survive."
    )


def claim(log_id: str, task_id: str) -> int | None:
    """Take the log for this delivery and count the attempt: its number, or None when the
    log is no longer processing or another live delivery holds it.

    The same delivery (same task id) may take it back: that is Celery redelivering the
    message of a worker that died mid-import."""
    free = (
        Q(heartbeat_at__isnull=True) | Q(heartbeat_at__lt=stale_before()) | Q(import_task=task_id)
    )
    taken = (
        FlightLog.objects.filter(pk=log_id, status=LogStatus.PROCESSING)
        .filter(free)
        .update(attempts=F("attempts") + 1, import_task=task_id, heartbeat_at=timezone.now())
    )
    if not taken:
        return None
    return FlightLog.objects.values_list("attempts", flat=True).get(pk=log_id)


def over_limit(attempt: int) -> bool:
    """True when the attempts before this one all stopped their worker, limit times."""
    return attempt > int(settings.LOGS_IMPORT_REDELIVERY_LIMIT)


def _beat(log_id: str, task_id: str, stop: threading.Event) -> None:
    try:
        while not stop.wait(float(settings.LOGS_HEARTBEAT_INTERVAL_S)):
            try:
                FlightLog.objects.filter(
                    pk=log_id, status=LogStatus.PROCESSING, import_task=task_id
                ).update(heartbeat_at=timezone.now())
            except DatabaseError as exc:  # the next beat tries again; the import goes on
                logger.warning("could not record that log %s is alive: %s", log_id, exc)
    finally:
        connections.close_all()  # this thread's own connection


@contextmanager
def heartbeat(log_id: str, task_id: str) -> Iterator[None]:
    """Show the sweep that this import is alive while the block runs (a thread: parsing
    may go long without a progress report)."""
    stop = threading.Event()
    thread = threading.Thread(
        target=_beat, args=(str(log_id), task_id, stop), name=f"heartbeat-{log_id}", daemon=True
    )
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(5)


def stuck_logs() -> list[FlightLog]:
    """Logs processing with no worker: started, then silent (heartbeat and last queueing)
    for LOGS_STUCK_AFTER_S, as when a worker died with its message (a lost machine, a
    hard time limit); or never started LOGS_UNSTARTED_AFTER_S after being queued, as when
    the message never reached the broker (a long queue of imports waits less than that)."""
    unstarted_before = timezone.now() - timedelta(seconds=float(settings.LOGS_UNSTARTED_AFTER_S))
    silent = Q(heartbeat_at__isnull=False, last_seen__lt=stale_before())
    lost = Q(heartbeat_at__isnull=True, queued_at__lt=unstarted_before)
    return list(
        FlightLog.objects.filter(status=LogStatus.PROCESSING)
        .annotate(last_seen=Greatest("heartbeat_at", "queued_at"))
        .filter(silent | lost)
    )


def mark_requeued(log: FlightLog) -> bool:
    """Compare-and-set: False when the log changed since it was found stuck."""
    return (
        FlightLog.objects.filter(
            pk=log.pk,
            status=LogStatus.PROCESSING,
            queued_at=log.queued_at,
            heartbeat_at=log.heartbeat_at,
            attempts=log.attempts,
        ).update(queued_at=timezone.now())
        == 1
    )

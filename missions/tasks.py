"""Celery entry points of the missions app: ids in, one domain call, idempotent."""

from __future__ import annotations

from celery import Task, shared_task
from django.db import OperationalError

from missions import collaboration, offline, panic, replacement
from missions.models import Event

# A lost database connection or a deadlock victim: run again (the task is idempotent)
# rather than leave a failing drone unreplaced.
RETRY = {"autoretry_for": (OperationalError,), "retry_backoff": 1, "max_retries": 5}


# An alarm's task is queued inside the alarm's transaction: it waits this many times
# ALARM_WAIT_S for the commit, then drops a rolled-back alarm (its redelivery queues anew).
ALARM_WAIT_S = 0.2
ALARM_WAITS = 25


def alarm_committed(task: Task, alarm_event_id: int | None) -> bool:
    """True once the alarm is on record; retries the task meanwhile; False if it never was."""
    if alarm_event_id is None or Event.objects.filter(pk=alarm_event_id).exists():
        return True
    if task.request.retries >= ALARM_WAITS:
        return False
    raise task.retry(countdown=ALARM_WAIT_S, max_retries=ALARM_WAITS)


@shared_task(name="missions.replace_drone", bind=True, acks_late=True, ignore_result=True, **RETRY)
def replace_drone(
    self: Task, mission_id: str, assignment_id: str, alarm_event_id: int | None = None
) -> None:
    """On a CRITICAL alarm. Safe to run twice: the second run finds the replacement."""
    if alarm_committed(self, alarm_event_id):
        replacement.replace_drone(
            mission_id=mission_id, assignment_id=assignment_id, alarm_event_id=alarm_event_id
        )


@shared_task(name="missions.collaborate", bind=True, acks_late=True, ignore_result=True, **RETRY)
def collaborate(
    self: Task, mission_id: str, assignment_id: str, alarm_event_id: int | None = None
) -> None:
    """On an OUT_MEASURE alarm. Once per mission: later runs only note the alarm."""
    if alarm_committed(self, alarm_event_id):
        collaboration.collaborate(
            mission_id=mission_id, assignment_id=assignment_id, alarm_event_id=alarm_event_id
        )


@shared_task(name="missions.resume_paused", ignore_result=True)
def resume_paused() -> list[str]:
    """Celery beat: give paused missions a drone as soon as one is available."""
    return replacement.resume_paused()


@shared_task(name="missions.replace_offline", acks_late=True, ignore_result=True, **RETRY)
def replace_offline(mission_id: str, assignment_id: str, event_id: int) -> None:
    """After the grace period: replace a drone still offline, as for a CRITICAL alarm."""
    offline.replace_if_still_offline(mission_id, assignment_id, event_id)


@shared_task(name="missions.relieve_panic_stations", ignore_result=True)
def relieve_panic_stations() -> list[str]:
    """Celery beat: a panic call's drone down to the battery reserve is relieved."""
    return panic.relieve_stations()

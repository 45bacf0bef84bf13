"""Celery entry points of the missions app: ids in, one domain call, idempotent."""

from __future__ import annotations

from celery import shared_task
from django.db import OperationalError

from missions import collaboration, replacement

# A lost database connection or a deadlock victim: run again (the task is idempotent)
# rather than leave a failing drone unreplaced.
RETRY = {"autoretry_for": (OperationalError,), "retry_backoff": 1, "max_retries": 5}


@shared_task(name="missions.replace_drone", acks_late=True, ignore_result=True, **RETRY)
def replace_drone(mission_id: str, assignment_id: str, alarm_event_id: int | None = None) -> None:
    """On a CRITICAL alarm. Safe to run twice: the second run finds the replacement."""
    replacement.replace_drone(
        mission_id=mission_id, assignment_id=assignment_id, alarm_event_id=alarm_event_id
    )


@shared_task(name="missions.collaborate", acks_late=True, ignore_result=True, **RETRY)
def collaborate(mission_id: str, assignment_id: str, alarm_event_id: int | None = None) -> None:
    """On an OUT_MEASURE alarm. Once per mission: later runs only note the alarm."""
    collaboration.collaborate(
        mission_id=mission_id, assignment_id=assignment_id, alarm_event_id=alarm_event_id
    )


@shared_task(name="missions.resume_paused", ignore_result=True)
def resume_paused() -> list[str]:
    """Celery beat: give paused missions a drone as soon as one is available."""
    return replacement.resume_paused()

"""The beat's sweep of due-soon and due warnings (calendar days grow without flights)."""

from __future__ import annotations

from celery import shared_task

from . import alerting


@shared_task(name="maintenance.warn")
def warn() -> int:
    return alerting.sweep()

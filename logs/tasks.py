"""The import task: load the log by id, parse it into its store, report the outcome."""

from __future__ import annotations

from celery import shared_task

from logs import services


@shared_task(name="logs.import", ignore_result=True, acks_late=True)
def import_flight_log(log_id: str) -> str:
    """Idempotent: a log already ready or failed (a redelivered message) is left alone."""
    return services.process_log(log_id)

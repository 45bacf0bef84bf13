"""The import task: load the log by id, parse it into its store, report the outcome."""

from __future__ import annotations

from celery import Task, shared_task

from logs import services


@shared_task(
    name="logs.import", bind=True, ignore_result=True, acks_late=True, reject_on_worker_lost=True
)
def import_flight_log(self: Task, log_id: str) -> str:
    """Idempotent: a log already ready or failed (a redelivered message) is left alone.
    A file the importers refuse, a MemoryError or the soft time limit ends the log failed
    in this delivery, and the task returns so its message is acknowledged: a deterministic
    failure is never retried. Only a worker process that dies has the message delivered
    again, up to LOGS_IMPORT_REDELIVERY_LIMIT."""
    return services.process_log(log_id, self.request.id)


@shared_task(name="logs.sweep_stuck", ignore_result=True)
def sweep_stuck_logs() -> dict[str, list[str]]:
    """Celery beat: logs left processing by a worker that is gone are retried or failed."""
    return services.sweep_stuck()

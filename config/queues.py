"""Which Celery queue a task goes to, by urgency (settings: SAFETY_TASKS and the queues).

Read at every call, so a queue named in the settings (or by a test) applies at once; a
task of no class, or a class whose queue is empty, goes to the default queue.
"""

from __future__ import annotations

from typing import Any

from django.conf import settings

LOG_TASKS = ("logs.import",)


def queue_for(name: str) -> str:
    """The queue of task `name`, or "" for the default queue."""
    if name in settings.SAFETY_TASKS:
        return settings.SAFETY_TASK_QUEUE
    if name in LOG_TASKS:
        return settings.LOGS_IMPORT_QUEUE
    return ""


def all_queues() -> list[str]:
    """Every queue a task may be routed to: the default one and each urgency class's."""
    default = getattr(settings, "CELERY_TASK_DEFAULT_QUEUE", "celery")
    named = {settings.SAFETY_TASK_QUEUE, settings.LOGS_IMPORT_QUEUE} - {""}
    return sorted({default, *named})


def route_task(
    name: str, args: Any, kwargs: Any, options: Any, task: Any = None, **kw: Any
) -> dict | None:
    """Celery router (CELERY_TASK_ROUTES): an explicit `queue=` of the caller still wins."""
    queue = queue_for(name)
    return {"queue": queue} if queue else None

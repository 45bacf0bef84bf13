from __future__ import annotations

from celery import shared_task

from . import retention


@shared_task(name="livevideo.prune_recordings")
def prune_recordings() -> int:
    return retention.prune()

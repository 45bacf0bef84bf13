from __future__ import annotations

from celery import shared_task
from django.conf import settings

from . import delivery


@shared_task(bind=True, max_retries=None, acks_late=True)
def deliver(self, delivery_id: str) -> str:  # type: ignore[no-untyped-def]
    """Try once; on failure again later, backing off, up to ALERT_MAX_ATTEMPTS tries."""
    outcome = delivery.attempt(delivery_id)
    if outcome == "retry":
        delay = settings.ALERT_RETRY_BASE_S * 2 ** min(self.request.retries, 6)
        raise self.retry(countdown=delay)
    return outcome

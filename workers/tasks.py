"""Celery task entry points. Each reads like a view: load by id, call the domain, decide."""

from __future__ import annotations

from celery import shared_task
from django.db import connection


@shared_task(name="workers.ping")
def ping(token: str) -> dict:
    """Prove a worker is alive and reaches the database (used by /health tests)."""
    with connection.cursor() as cursor:
        cursor.execute("SELECT now()")
        (now,) = cursor.fetchone()
    return {"pong": token, "db_time": now.isoformat()}

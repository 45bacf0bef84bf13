"""Celery task entry points of the fleet: each loads, calls the domain, and returns."""

from __future__ import annotations

from celery import shared_task

from fleet.heartbeats import sweep_offline


@shared_task(name="fleet.sweep_offline", ignore_result=True)
def sweep_offline_drones() -> list[str]:
    """Mark drones offline after missed heartbeats (Celery beat, every few seconds)."""
    return sweep_offline()

"""Closing flights: one task per disarming, and a beat sweep that catches up."""

from __future__ import annotations

from celery import shared_task

from . import building


@shared_task(name="records.close_flight")
def close_flight(open_flight_pk: int) -> int | None:
    record = building.close_flight(open_flight_pk)
    return None if record is None else record.pk


@shared_task(name="records.settle")
def settle() -> dict[str, int]:
    return building.reconcile()

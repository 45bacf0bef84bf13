"""What opens and marks flights: the Drone Identifier's arming changes."""

from __future__ import annotations

import logging
from datetime import datetime

from django.conf import settings
from django.db import transaction

from fleet.models import Drone
from fleet.signals import drones_arming_changed

from . import building

log = logging.getLogger(__name__)


def connect() -> None:
    drones_arming_changed.connect(on_arming_changed, dispatch_uid="records-arming")


def on_arming_changed(
    sender: object, changes: list[tuple[int, bool, datetime, dict | None]], **kwargs: object
) -> None:
    drones = Drone.objects.in_bulk([pk for pk, *_ in changes])
    for pk, armed, seen, mission in changes:
        drone = drones.get(pk)
        if drone is None:
            continue
        if armed:
            building.open_flight(drone, seen, mission)
            continue
        flight = building.mark_disarmed(drone, seen)
        if flight is not None:
            transaction.on_commit(lambda f=flight.pk: _close_later(f))


def _close_later(open_flight_pk: int) -> None:
    """Close once the telemetry of the flight's last seconds is stored; the beat's
    `records.settle` closes it if this task is lost."""
    from . import tasks

    try:
        tasks.close_flight.apply_async(
            args=[open_flight_pk], countdown=settings.RECORDS_CLOSE_DELAY_S
        )
    except Exception as exc:  # the Celery broker away: the beat's sweep closes it
        log.warning("flight %s left for the sweep: %s", open_flight_pk, exc)

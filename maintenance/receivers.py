"""What makes maintenance look again: a flight recorded adds hours and a flight."""

from __future__ import annotations

from django.db import transaction
from django.db.models.signals import post_save

from fleet.models import Drone
from records.models import FlightRecord

from . import alerting


def connect() -> None:
    post_save.connect(flight_recorded, sender=FlightRecord, dispatch_uid="maintenance-flight")


def flight_recorded(
    sender: object, instance: FlightRecord, created: bool, **kwargs: object
) -> None:
    """Once the record is committed, warn of the drone's items it brought near or to due."""
    if created and instance.drone_id is not None:
        drone_pk = instance.drone_id
        transaction.on_commit(lambda: _warn(drone_pk))


def _warn(drone_pk: int) -> None:
    drone = Drone.objects.select_related("organisation").filter(pk=drone_pk).first()
    if drone is not None:
        alerting.warn(drone)

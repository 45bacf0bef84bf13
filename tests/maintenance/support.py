"""Maintenance test helpers: flight records as the ground writes them, and API clients."""

from __future__ import annotations

from datetime import timedelta

from django.utils import timezone
from rest_framework.test import APIClient

from fleet.models import Drone
from records.models import FlightRecord, Origin


def flown(drone, minutes: float, count: int = 1) -> None:  # type: ignore[no-untyped-def]
    """`count` flights of `minutes` each, one an hour, the last an hour ago; the drone is
    dated back to have joined the fleet before the first."""
    now = timezone.now()
    joined = now - timedelta(hours=count + 1)
    Drone.objects.filter(pk=drone.pk, created_at__gt=joined).update(created_at=joined)
    drone.refresh_from_db()
    for n in range(count):
        started = now - timedelta(hours=count - n)
        FlightRecord.objects.create(
            organisation_id=drone.organisation_id,
            drone=drone,
            drone_ident=drone.drone_id,
            origin=Origin.COMMAND,
            started_at=started,
            ended_at=started + timedelta(minutes=minutes),
            duration_s=minutes * 60.0,
        )


def api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client

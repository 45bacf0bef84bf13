"""Missions test helpers: drones that look online, an outbox of our own, areas in metres."""

from __future__ import annotations

import json
from urllib.parse import urlsplit, urlunsplit

import pytest

from .planning import AVEIRO, point_at, rectangle

__all__ = ["AVEIRO", "point_at", "rectangle"]
# Our own Redis database for the gateway outbox: other suites running at the same time
# have gateways popping the default one.
OUTBOX_DB = 9


def online_drone(org, drone_id: str, north: float = 0.0, east: float = 0.0, battery: float = 0.9):  # type: ignore[no-untyped-def]
    from fleet.models import Drone

    lat, lon = point_at(north, east)
    drone, _ = Drone.objects.update_or_create(
        drone_id=drone_id,
        defaults={
            "organisation": org,
            "online": True,
            "lat": lat,
            "lon": lon,
            "alt": 0.0,
            "battery_remaining": battery,
            "battery_voltage": 16.4,
        },
    )
    return drone


def redis_url_with_db(url: str, db: int) -> str:
    parts = urlsplit(url)
    return urlunsplit(parts._replace(path=f"/{db}"))


@pytest.fixture
def outbox(settings):  # type: ignore[no-untyped-def]
    """The gateway outbox in a Redis database of our own, emptied; `.items()` reads it."""
    from workers import outbox

    settings.REDIS_URL = redis_url_with_db(settings.REDIS_URL, OUTBOX_DB)
    outbox._sync_client = None
    client = outbox.sync_redis()
    client.delete(outbox.outbox_key())

    class Outbox:
        url = settings.REDIS_URL

        def items(self) -> list[dict]:
            return [json.loads(raw) for raw in client.lrange(outbox.outbox_key(), 0, -1)]

        def clear(self) -> None:
            client.delete(outbox.outbox_key())

    yield Outbox()
    client.delete(outbox.outbox_key())
    outbox._sync_client = None

"""The panic button: the nearest available drone arms, climbs to 10 m ([Paula 2018], §5.1),
flies to the caller and hovers there (no land: it stays until an operator decides)."""

from __future__ import annotations

from typing import Any

from django.conf import settings

from fleet.models import Organisation
from missions.services import MissionError, Started, create_mission, start_mission
from onboard import protocol


def panic_steps(lat: float, lon: float, altitude: float) -> list[dict]:
    return [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": altitude}},
        # Climb first, then fly: each stage is timed on its own ([Paula 2018], figure 5.8).
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": lat, "lon": lon}},
        {"command": "wait_for_flight", "params": {}},
    ]


def call_drone(*, organisation: Organisation, lat: Any, lon: Any, user: Any = None) -> Started:
    """Create and start a panic mission to the caller's position."""
    try:
        lat = protocol.latitude(lat, "lat")
        lon = protocol.longitude(lon, "lon")
    except protocol.ProtocolError as exc:
        raise MissionError(exc.field, exc.message) from None
    altitude = settings.MISSIONS_PANIC_ALTITUDE
    mission = create_mission(
        organisation=organisation,
        name=f"Panic call at {lat:.5f}, {lon:.5f}",
        steps=panic_steps(lat, lon, altitude),
        altitude=altitude,
        user=user,
    )
    try:
        return start_mission(mission, user=user)
    except MissionError:
        mission.delete()
        raise

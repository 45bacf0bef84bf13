"""What the reservations endpoint shows."""

from __future__ import annotations

from datetime import UTC, datetime

from fleet.models import Organisation

from . import reservations
from .models import Reservation


def _iso(t: float) -> str:
    return datetime.fromtimestamp(t, tz=UTC).isoformat()


def leg_body(values: list[float], radius_m: float) -> dict:
    lat0, lon0, lat1, lon1, low, high, t0, t1 = values[:8]
    return {
        "start": [lat0, lon0],
        "end": [lat1, lon1],
        "radius_m": radius_m,
        "band_m": [low, high],
        "window": [_iso(t0), _iso(t1)],
    }


def reservation_body(row: Reservation) -> dict:
    return {
        "id": row.pk,
        "drone_id": row.drone.drone_id,
        "kind": row.kind,
        "mission_id": None if row.assignment is None else str(row.assignment.mission_id),
        "command": row.command,
        "window": [row.starts_at.isoformat(), row.ends_at.isoformat()],
        "separation_m": {"horizontal": row.horizontal_min_m, "vertical": row.vertical_min_m},
        "legs": [leg_body(values, row.radius_m) for values in row.legs],
    }


def reservations_body(organisation: Organisation) -> dict:
    """The organisation's own active reservations (never another's, even site-wide)."""
    reservations.sweep()
    rows = (
        Reservation.objects.filter(organisation=organisation, ended_at__isnull=True)
        .select_related("drone", "assignment")
        .order_by("starts_at", "pk")
    )
    horizontal, vertical = reservations.minima_for(organisation.pk)
    return {
        "organisation": organisation.slug,
        "separation_m": {"horizontal": horizontal, "vertical": vertical},
        "reservations": [reservation_body(row) for row in rows],
    }

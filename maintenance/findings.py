"""Findings the platform opens on one drone: an open maintenance item, like a bulletin for
that drone alone, that keeps it on the ground until an admin signs it off. The flight-log
trends call `open_finding` (LOGS_TREND_MAINTENANCE_FUNCTION) for the organisations that
ask for it (LOGS_TREND_MAINTENANCE) when a figure drifts."""

from __future__ import annotations

from fleet.models import Drone

from .models import Bulletin
from .schedules import TEXT_MAX, TITLE_MAX

PLATFORM = "platform"


def open_finding(*, drone: Drone, title: str, detail: str, source: str) -> Bulletin:
    """The finding `source` opened on the drone; the same source opens one, however often."""
    finding, _ = Bulletin.objects.get_or_create(
        organisation_id=drone.organisation_id,
        source=source[:200],
        defaults={
            "drone": drone,
            "title": title[:TITLE_MAX],
            "text": detail[:TEXT_MAX] or title[:TITLE_MAX],
            "issued_by_name": PLATFORM,
        },
    )
    return finding

"""Terrain: elevation models imported offline and the clearance of legs above them.

`elevation(lat, lon)` and `clearance_along(start_lla, end_lla)` are the lookups
(terrain/lookup.py); they read the database, so they import it when first called.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from terrain.lookup import LegClearance


def elevation(lat: float, lon: float) -> float | None:
    """Metres above mean sea level at (lat, lon), bilinear; None without terrain or at a void."""
    from terrain.lookup import elevation as lookup

    return lookup(lat, lon)


def clearance_along(
    start_lla: Sequence[float], end_lla: Sequence[float], spacing: float | None = None
) -> LegClearance:
    """The lowest clearance of a straight leg above the terrain, where, and its gaps."""
    from terrain.lookup import clearance_along as lookup

    return lookup(start_lla, end_lla, spacing)

"""A local metric frame: WGS84 lat/lon ↔ North/East metres about a reference point.

The linearisation is the one the drones use (dRonin's GCS, as in [Paula 2018], fig. 4.13):
N = R·Δlat, E = R·cos(lat₀)·Δlon with R = 6 378 137 m. Over a mission area
(a few km) its error is far below GPS noise, and planning in the same frame as the
Navigation Processor keeps the ground's "one step apart" equal to the drone's.
Everything is vectorised: arrays of any shape go in, arrays of the same shape come out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

EARTH_RADIUS_M = 6_378_137.0
# Beyond this latitude cos(lat) is too small for an east axis worth planning on.
MAX_ABS_LATITUDE = 89.0


@dataclass(frozen=True)
class LocalFrame:
    """North/East metres about (lat0, lon0); `alt0` raises the radius, as the drones do."""

    lat0: float
    lon0: float
    alt0: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lat0) and abs(self.lat0) <= MAX_ABS_LATITUDE):
            raise ValueError(f"reference latitude {self.lat0!r} is outside ±{MAX_ABS_LATITUDE}°")
        if not (math.isfinite(self.lon0) and -180.0 <= self.lon0 <= 180.0):
            raise ValueError(f"reference longitude {self.lon0!r} is outside ±180°")

    @property
    def _radius(self) -> float:
        return EARTH_RADIUS_M + self.alt0

    @property
    def _cos_lat0(self) -> float:
        return math.cos(math.radians(self.lat0))

    def to_ne(self, lat: ArrayLike, lon: ArrayLike) -> tuple[NDArray, NDArray]:
        """Degrees → (north, east) metres."""
        lat = np.asarray(lat, dtype=float)
        lon = np.asarray(lon, dtype=float)
        # Wrap the longitude difference so an area across the antimeridian stays compact.
        dlon = (lon - self.lon0 + 180.0) % 360.0 - 180.0
        north = self._radius * np.radians(lat - self.lat0)
        east = self._radius * self._cos_lat0 * np.radians(dlon)
        return north, east

    def to_latlon(self, north: ArrayLike, east: ArrayLike) -> tuple[NDArray, NDArray]:
        """(north, east) metres → degrees, longitude wrapped into [-180, 180)."""
        north = np.asarray(north, dtype=float)
        east = np.asarray(east, dtype=float)
        lat = self.lat0 + np.degrees(north / self._radius)
        lon = self.lon0 + np.degrees(east / (self._radius * self._cos_lat0))
        lon = (lon + 180.0) % 360.0 - 180.0
        return lat, lon

    def point_to_latlon(self, ne: ArrayLike) -> tuple[float, float]:
        north, east = np.asarray(ne, dtype=float)
        lat, lon = self.to_latlon(north, east)
        return float(lat), float(lon)


def distance_m(lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike) -> NDArray:
    """Horizontal distance in metres (haversine on the same sphere), vectorised."""
    p1, l1, p2, l2 = (np.radians(np.asarray(x, dtype=float)) for x in (lat1, lon1, lat2, lon2))
    a = np.sin((p2 - p1) / 2.0) ** 2 + np.cos(p1) * np.cos(p2) * np.sin((l2 - l1) / 2.0) ** 2
    return 2.0 * EARTH_RADIUS_M * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))

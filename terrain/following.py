"""Terrain following: a path flown at a constant height above the ground, as
QGroundControl's terrain-following survey flies it [QGC survey].

Every leg (home → first waypoint, then waypoint to waypoint) is sampled four times as
densely as the clearance check samples it (terrain/lookup.py: half a cell apart), since
the ground between samples bends (bilinear interpolation is quadratic along a line
across a cell) and the chord must stay within the tolerance there too. The terrain profile under the leg
is simplified by Douglas–Peucker [Douglas 1973] with the tolerance as its distance: a point
is added where the ground departs from the straight line between the kept points by more
than the tolerance, so between any two points the drone flies at the height above ground
it was given, give or take the tolerance (QGroundControl's "Tolerance", 10 m by default).

Heights come out above home (the ground at home is height 0), the frame missions fly in;
a point the terrain does not cover, or covers with a void, refuses the whole path.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from onboard.envelope import latlon_to_ne
from terrain.lookup import Surface

# Profile samples per clearance-check sample.
DENSER = 4
# QGroundControl's default terrain-following tolerance [QGC survey].
DEFAULT_TOLERANCE_M = 10.0
MIN_TOLERANCE_M = 1.0


class FollowingError(ValueError):
    """The path cannot follow the terrain; `field` names the input at fault."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field
        self.message = message


@dataclass(frozen=True)
class Point:
    """A point of the path: where, its height above home, the ground under it (metres
    above mean sea level), and whether it is one of the given waypoints."""

    lat: float
    lon: float
    height: float
    ground: float
    waypoint: bool

    def to_dict(self) -> dict:
        return {
            "lat": self.lat,
            "lon": self.lon,
            "height_m": round(self.height, 2),
            "ground_m": round(self.ground, 2),
            "waypoint": self.waypoint,
        }


def _simplify(along: np.ndarray, ground: np.ndarray, tolerance: float) -> list[int]:
    """Indexes kept by Douglas–Peucker on the profile (along, ground); both ends kept."""
    kept = {0, len(along) - 1}
    stack = [(0, len(along) - 1)]
    while stack:
        first, last = stack.pop()
        if last - first < 2:
            continue
        span = along[last] - along[first]
        slope = (ground[last] - ground[first]) / span if span > 0 else 0.0
        inner = slice(first + 1, last)
        chord = ground[first] + slope * (along[inner] - along[first])
        deviation = np.abs(ground[inner] - chord)
        worst = int(np.argmax(deviation))
        if deviation[worst] > tolerance:
            middle = first + 1 + worst
            kept.add(middle)
            stack += [(first, middle), (middle, last)]
    return sorted(kept)


def _profile(surface: Surface, start: Sequence[float], end: Sequence[float], step: float):  # type: ignore[no-untyped-def]
    """Samples of the leg start → end: (latitudes, longitudes, metres along, ground)."""
    length = math.hypot(*latlon_to_ne(end[0], end[1], start))
    count = max(2, math.ceil(length / step) + 1)
    fractions = np.linspace(0.0, 1.0, count)
    lats = start[0] + (end[0] - start[0]) * fractions
    lons = start[1] + (end[1] - start[1]) * fractions
    ground, _ = surface.sample(lats, lons)
    return lats, lons, fractions * length, ground


def _uncovered(lats: np.ndarray, lons: np.ndarray, ground: np.ndarray, leg: int) -> None:
    missing = np.flatnonzero(np.isnan(ground))
    if missing.size:
        i = int(missing[0])
        raise FollowingError(
            "terrain_following",
            f"no terrain (or a void) at ({lats[i]:.5f}, {lons[i]:.5f}) on leg {leg}: "
            "a path cannot follow terrain that is not imported",
        )


def follow(
    home: Sequence[float],
    waypoints: Sequence[Sequence[float]],
    height_agl: float,
    tolerance: float = DEFAULT_TOLERANCE_M,
) -> list[Point]:
    """The waypoints (and the points added between them) at `height_agl` above the
    terrain, heights above the ground at home; home itself is not in the result."""
    if not (math.isfinite(tolerance) and tolerance >= MIN_TOLERANCE_M):
        raise FollowingError(
            "tolerance_m", f"must be a number of metres, at least {MIN_TOLERANCE_M:g}"
        )
    corners = [(float(home[0]), float(home[1]))] + [(float(p[0]), float(p[1])) for p in waypoints]
    lats = np.array([c[0] for c in corners])
    lons = np.array([c[1] for c in corners])
    surface = Surface.covering(lons.min(), lats.min(), lons.max(), lats.max())
    starts = np.column_stack((lats[:-1], lons[:-1]))
    step = (
        surface.spacing(starts, np.column_stack((lats[1:], lons[1:]))) if len(corners) > 1 else None
    )
    home_ground = surface.elevation(*corners[0])
    if step is None or home_ground is None:
        raise FollowingError("terrain_following", "no terrain imported at home: heights above the ground cannot be placed")  # fmt: skip
    step /= DENSER
    points: list[Point] = []
    for leg, (start, end) in enumerate(zip(corners, corners[1:], strict=False)):
        plats, plons, along, ground = _profile(surface, start, end, step)
        _uncovered(plats, plons, ground, leg)
        for i in _simplify(along, ground, tolerance)[1:]:
            last = i == len(along) - 1
            height = float(ground[i]) + height_agl - home_ground
            points.append(Point(float(plats[i]), float(plons[i]), height, float(ground[i]), last))
    return points

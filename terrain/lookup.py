"""Elevations from the imported grids, and the clearance of a straight leg above them.

Between samples the elevation is interpolated bilinearly from the four samples around
the point; where any of them is a void there is no elevation (a void is never read as
sea level). Where grids overlap, the newest import with an elevation at the point wins.

A leg is sampled every half of the smallest cell (in metres) of the grids under it, so
no cell it crosses goes unsampled and a ridge between two waypoints is seen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from onboard.envelope import EARTH_RADIUS, latlon_to_ne
from terrain import store
from terrain.models import TerrainTile

METRES_PER_DEGREE = EARTH_RADIUS * math.pi / 180.0
# Samples per cell along a leg: two, so that no cell is stepped over.
SAMPLES_PER_CELL = 2
# A point this close to a grid's edge (degrees) is on it: SRTM tiles meet exactly.
EDGE_EPSILON = 1e-9
NO_TERRAIN = "no terrain"
VOID = "void"
LLA = Sequence[float]  # latitude, longitude, altitude above mean sea level (m)


@dataclass(frozen=True)
class _Tile:
    pk: int
    north: float
    west: float
    south: float
    east: float
    dlat: float
    dlon: float

    def contains(self, lats: np.ndarray, lons: np.ndarray) -> np.ndarray:
        return (
            (lats >= self.south - EDGE_EPSILON)
            & (lats <= self.north + EDGE_EPSILON)
            & (lons >= self.west - EDGE_EPSILON)
            & (lons <= self.east + EDGE_EPSILON)
        )

    def cell_metres(self, lat: float) -> float:
        across = self.dlon * METRES_PER_DEGREE * max(math.cos(math.radians(lat)), 1e-6)
        return min(self.dlat * METRES_PER_DEGREE, across)


def _bilinear(grid: np.ndarray, tile: _Tile, lats: np.ndarray, lons: np.ndarray) -> np.ndarray:
    rows, cols = grid.shape
    fr = (tile.north - lats) / tile.dlat
    fc = (lons - tile.west) / tile.dlon
    r0 = np.clip(np.floor(fr).astype(np.intp), 0, rows - 2)
    c0 = np.clip(np.floor(fc).astype(np.intp), 0, cols - 2)
    t = np.clip(fr - r0, 0.0, 1.0)
    u = np.clip(fc - c0, 0.0, 1.0)
    top = grid[r0, c0] * (1.0 - u) + grid[r0, c0 + 1] * u
    bottom = grid[r0 + 1, c0] * (1.0 - u) + grid[r0 + 1, c0 + 1] * u
    # NaN (a void) in any of the four samples makes the result NaN.
    return top * (1.0 - t) + bottom * t


@dataclass(frozen=True)
class Gap:
    """A stretch of a leg (metres from its start) with no elevation, and why."""

    start_m: float
    end_m: float
    reason: str

    def to_dict(self) -> dict:
        return {"from_m": round(self.start_m, 1), "to_m": round(self.end_m, 1), "reason": self.reason}  # fmt: skip


@dataclass(frozen=True)
class LegClearance:
    """The lowest clearance along a leg (None where no part of it has terrain), where it
    is (latitude, longitude, metres along the leg) and the stretches without terrain."""

    length_m: float
    samples: int
    spacing_m: float | None
    minimum: float | None = None
    at: tuple[float, float, float] | None = None
    terrain_at: float | None = None
    gaps: list[Gap] = field(default_factory=list)

    @property
    def fully_covered(self) -> bool:
        return not self.gaps


def _runs(codes: np.ndarray) -> list[tuple[int, int, int]]:
    """(first, last, code) of every run of equal non-zero codes."""
    edges = np.flatnonzero(np.diff(codes)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges - 1, [len(codes) - 1]))
    return [(int(a), int(b), int(codes[a])) for a, b in zip(starts, ends, strict=True) if codes[a]]


class Surface:
    """The grids under an area, newest first, sampled together."""

    def __init__(self, tiles: Sequence[_Tile]) -> None:
        self.tiles = list(tiles)

    @classmethod
    def covering(cls, west: float, south: float, east: float, north: float) -> Surface:
        rows = TerrainTile.objects.filter(
            west__lte=east + EDGE_EPSILON,
            east__gte=west - EDGE_EPSILON,
            south__lte=north + EDGE_EPSILON,
            north__gte=south - EDGE_EPSILON,
        ).order_by("-created_at", "-id")
        fields = ("pk", "north", "west", "south", "east", "cell_lat", "cell_lon")
        return cls([_Tile(*values) for values in rows.values_list(*fields)])

    def sample(self, lats: np.ndarray, lons: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(elevations with NaN where none, whether each point lies on some grid)."""
        heights = np.full(lats.shape, np.nan)
        covered = np.zeros(lats.shape, dtype=bool)
        for tile in self.tiles:
            inside = tile.contains(lats, lons)
            grid = store.open_grid(tile.pk) if inside.any() else None
            if grid is None:
                continue
            covered |= inside
            wanted = inside & np.isnan(heights)
            if wanted.any():
                heights[wanted] = _bilinear(grid, tile, lats[wanted], lons[wanted])
        return heights, covered

    def elevation(self, lat: float, lon: float) -> float | None:
        heights, _ = self.sample(np.array([float(lat)]), np.array([float(lon)]))
        return None if math.isnan(heights[0]) else float(heights[0])

    def spacing(self, start: LLA, end: LLA) -> float | None:
        """Half the smallest cell (metres) of the grids under the leg; None without any."""
        lats, lons = (start[0], end[0]), (start[1], end[1])
        box = (min(lons), min(lats), max(lons), max(lats))
        under = [t for t in self.tiles if t.west <= box[2] and t.east >= box[0]
                 and t.south <= box[3] and t.north >= box[1]]  # fmt: skip
        if not under:
            return None
        widest = max(abs(lats[0]), abs(lats[1]))
        return min(t.cell_metres(widest) for t in under) / SAMPLES_PER_CELL

    def clearance_along(self, start: LLA, end: LLA, spacing: float | None = None) -> LegClearance:
        """The clearance of the straight leg start → end (altitude linear along it)."""
        north, east = latlon_to_ne(end[0], end[1], start)
        length = math.hypot(north, east)
        grid_spacing = self.spacing(start, end)
        if grid_spacing is None:
            return LegClearance(length, 0, None, gaps=[Gap(0.0, length, NO_TERRAIN)])
        step = min(grid_spacing, spacing) if spacing else grid_spacing
        count = max(2, math.ceil(length / step) + 1) if length > 0 else 1
        fractions = np.linspace(0.0, 1.0, count)
        lats = start[0] + (end[0] - start[0]) * fractions
        lons = start[1] + (end[1] - start[1]) * fractions
        alts = start[2] + (end[2] - start[2]) * fractions
        heights, covered = self.sample(lats, lons)
        return _leg_result(length, step, fractions * length, lats, lons, alts, heights, covered)


def _leg_result(
    length: float,
    step: float,
    along: np.ndarray,
    lats: np.ndarray,
    lons: np.ndarray,
    alts: np.ndarray,
    heights: np.ndarray,
    covered: np.ndarray,
) -> LegClearance:
    missing = np.isnan(heights)
    codes = np.where(missing, np.where(covered, 1, 2), 0)
    reasons = {1: VOID, 2: NO_TERRAIN}
    gaps = [Gap(float(along[a]), float(along[b]), reasons[c]) for a, b, c in _runs(codes)]
    if missing.all():
        return LegClearance(length, len(along), step, gaps=gaps)
    clearance = np.where(missing, np.inf, alts - np.nan_to_num(heights))
    i = int(np.argmin(clearance))
    return LegClearance(
        length_m=length,
        samples=len(along),
        spacing_m=step,
        minimum=float(clearance[i]),
        at=(float(lats[i]), float(lons[i]), float(along[i])),
        terrain_at=float(heights[i]),
        gaps=gaps,
    )


def _leg_box(start: LLA, end: LLA) -> tuple[float, float, float, float]:
    return (min(start[1], end[1]), min(start[0], end[0]), max(start[1], end[1]), max(start[0], end[0]))  # fmt: skip


def elevation(lat: float, lon: float) -> float | None:
    """The terrain's elevation (metres above mean sea level) at a point, bilinear between
    samples; None where no grid covers it or a void is among the samples around it."""
    return Surface.covering(lon, lat, lon, lat).elevation(lat, lon)


def clearance_along(start_lla: LLA, end_lla: LLA, spacing: float | None = None) -> LegClearance:
    """The lowest clearance of the straight leg between two (lat, lon, altitude above mean
    sea level) points, where it occurs, and the stretches with no terrain."""
    return Surface.covering(*_leg_box(start_lla, end_lla)).clearance_along(
        start_lla, end_lla, spacing
    )

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
from django.db.models import F

from onboard.envelope import EARTH_RADIUS
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

    def reaches(self, lats: np.ndarray, lons: np.ndarray) -> np.ndarray:
        """Within half a cell of the grid's outer samples: the outer half of its edge
        pixels (a pixel-is-area grid's own extent), which also closes the one-cell strip
        between two tiles that share no edge samples."""
        half_lat, half_lon = self.dlat / 2, self.dlon / 2
        return (
            (lats >= self.south - half_lat)
            & (lats <= self.north + half_lat)
            & (lons >= self.west - half_lon)
            & (lons <= self.east + half_lon)
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
    # The highest clearance along the leg and where (latitude, longitude, metres along),
    # and the clearance at its start (None over a gap): the ceiling above the terrain.
    highest: float | None = None
    highest_at: tuple[float, float, float] | None = None
    at_start: float | None = None

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
        """The grids whose samples, or the outer half of their edge cells, reach the box."""
        rows = TerrainTile.objects.filter(
            west__lte=east + EDGE_EPSILON + F("cell_lon"),
            east__gte=west - EDGE_EPSILON - F("cell_lon"),
            south__lte=north + EDGE_EPSILON + F("cell_lat"),
            north__gte=south - EDGE_EPSILON - F("cell_lat"),
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
        if not covered.all():
            self._beside_edges(lats, lons, heights, covered)
        return heights, covered

    def _beside_edges(
        self, lats: np.ndarray, lons: np.ndarray, heights: np.ndarray, covered: np.ndarray
    ) -> None:
        """A point on no grid but within half a cell of one takes that grid's edge (the
        interpolation held at its outer samples); near two, the higher ground, which can
        only lower the clearance."""
        outside = ~covered
        edge = np.full(lats.shape, np.nan)
        reached = np.zeros(lats.shape, dtype=bool)
        for tile in self.tiles:
            near = outside & tile.reaches(lats, lons)
            grid = store.open_grid(tile.pk) if near.any() else None
            if grid is None:
                continue
            reached |= near
            edge[near] = np.fmax(edge[near], _bilinear(grid, tile, lats[near], lons[near]))
        heights[reached] = edge[reached]
        covered |= reached

    def elevation(self, lat: float, lon: float) -> float | None:
        heights, _ = self.sample(np.array([float(lat)]), np.array([float(lon)]))
        return None if math.isnan(heights[0]) else float(heights[0])

    def spacing(self, starts: np.ndarray, ends: np.ndarray) -> float | None:
        """Half the smallest cell (metres) of the grids under the legs; None without any."""
        lats = np.concatenate((starts[:, 0], ends[:, 0]))
        lons = np.concatenate((starts[:, 1], ends[:, 1]))
        box = (lons.min(), lats.min(), lons.max(), lats.max())
        under = [t for t in self.tiles if t.west <= box[2] and t.east >= box[0]
                 and t.south <= box[3] and t.north >= box[1]]  # fmt: skip
        if not under:
            return None
        widest = float(np.abs(lats).max())
        return min(t.cell_metres(widest) for t in under) / SAMPLES_PER_CELL

    def clearance_along(self, start: LLA, end: LLA, spacing: float | None = None) -> LegClearance:
        """The clearance of the straight leg start → end (altitude linear along it)."""
        return self.clearances(np.array([start], float), np.array([end], float), spacing)[0]

    def clearances(
        self,
        starts: np.ndarray,
        ends: np.ndarray,
        spacing: float | None = None,
        highest: bool = True,
    ) -> list[LegClearance]:
        """The clearance of each leg starts[i] → ends[i] (rows of latitude, longitude and
        altitude above mean sea level): every leg's samples, no farther apart than
        `spacing` nor than half a cell, interpolated together in one pass."""
        lengths = _lengths(starts, ends)
        step = self.spacing(starts, ends)
        if step is None:
            return [LegClearance(float(n), 0, None, gaps=[Gap(0.0, float(n), NO_TERRAIN)]) for n in lengths]  # fmt: skip
        step = min(step, spacing) if spacing else step
        counts = np.where(lengths > 0, np.maximum(2, np.ceil(lengths / step).astype(int) + 1), 1)
        offsets = np.concatenate(([0], np.cumsum(counts)[:-1]))
        leg = np.repeat(np.arange(len(counts)), counts)
        fractions = (np.arange(counts.sum()) - offsets[leg]) / np.maximum(counts - 1, 1)[leg]
        points = starts[leg] + (ends[leg] - starts[leg]) * fractions[:, None]
        heights, covered = self.sample(points[:, 0], points[:, 1])
        samples = _Samples(points, fractions * lengths[leg], heights, covered, offsets, counts)
        return samples.legs(lengths, step, highest)


def _lengths(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Horizontal length of each leg in metres, in the local frame about its start
    (onboard.envelope.latlon_to_ne)."""
    north = EARTH_RADIUS * np.radians(ends[:, 0] - starts[:, 0])
    dlon = (ends[:, 1] - starts[:, 1] + 180.0) % 360.0 - 180.0
    east = EARTH_RADIUS * np.cos(np.radians(starts[:, 0])) * np.radians(dlon)
    return np.hypot(north, east)


@dataclass
class _Samples:
    """The samples of many legs, leg after leg (`offsets`, `counts`)."""

    points: np.ndarray  # latitude, longitude, altitude
    along: np.ndarray
    heights: np.ndarray
    covered: np.ndarray
    offsets: np.ndarray
    counts: np.ndarray

    def lowest(self) -> tuple[np.ndarray, np.ndarray]:
        """Each leg's lowest clearance (inf without terrain) and the sample it is at."""
        missing = np.isnan(self.heights)
        clearance = np.where(missing, np.inf, self.points[:, 2] - np.nan_to_num(self.heights))
        minima = np.minimum.reduceat(clearance, self.offsets)
        leg = np.repeat(np.arange(len(self.counts)), self.counts)
        candidates = np.flatnonzero(clearance == minima[leg])
        _, first = np.unique(leg[candidates], return_index=True)
        return minima, candidates[first]

    def highest(self) -> tuple[np.ndarray, np.ndarray]:
        """Each leg's highest clearance (-inf without terrain) and the sample it is at."""
        missing = np.isnan(self.heights)
        clearance = np.where(missing, -np.inf, self.points[:, 2] - np.nan_to_num(self.heights))
        maxima = np.maximum.reduceat(clearance, self.offsets)
        leg = np.repeat(np.arange(len(self.counts)), self.counts)
        candidates = np.flatnonzero(clearance == maxima[leg])
        _, first = np.unique(leg[candidates], return_index=True)
        return maxima, candidates[first]

    def at_start(self) -> list[float | None]:
        """Each leg's clearance at its first sample, None over a gap."""
        first = self.points[self.offsets, 2] - self.heights[self.offsets]
        return [None if math.isnan(v) else v for v in first.tolist()]

    def _tops(self, wanted: bool) -> tuple[list, list, list]:
        """Per leg: the highest clearance, where (latitude, longitude, metres along) and the
        clearance at its start; None each when not `wanted`."""
        if not wanted:
            nothing = [None] * len(self.counts)
            return nothing, nothing, nothing
        tops, at = self.highest()
        places = np.column_stack((self.points[at, :2], self.along[at])).tolist()
        return tops.tolist(), [tuple(p) for p in places], self.at_start()

    def gaps(self, i: int) -> list[Gap]:
        a, b = int(self.offsets[i]), int(self.offsets[i] + self.counts[i])
        missing = np.isnan(self.heights[a:b])
        codes = np.where(missing, np.where(self.covered[a:b], 1, 2), 0)
        reasons = {1: VOID, 2: NO_TERRAIN}
        along = self.along[a:b]
        return [Gap(float(along[x]), float(along[y]), reasons[c]) for x, y, c in _runs(codes)]

    def legs(self, lengths: np.ndarray, step: float, highest: bool = True) -> list[LegClearance]:
        """Each leg's clearance; its highest and its start too when `highest`."""
        lowest, at = self.lowest()
        missing = np.add.reduceat(np.isnan(self.heights).astype(int), self.offsets) > 0
        minima, incomplete, counts = lowest.tolist(), missing.tolist(), self.counts.tolist()
        along, heights = self.along[at].tolist(), self.heights[at].tolist()
        places = self.points[at, :2].tolist()
        tops, top_places, starts = self._tops(highest)
        found = []
        for i, length in enumerate(lengths.tolist()):
            gaps = self.gaps(i) if incomplete[i] else []
            if not math.isfinite(minima[i]):
                found.append(LegClearance(length, counts[i], step, gaps=gaps))
                continue
            lat, lon = places[i]
            found.append(LegClearance(
                length, counts[i], step, minima[i], (lat, lon, along[i]), heights[i], gaps,
                highest=tops[i], highest_at=top_places[i], at_start=starts[i],
            ))  # fmt: skip
        return found


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

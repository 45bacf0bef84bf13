"""Finding the first conflict between a flight's corridors and the reserved ones (no Django).

Two corridors conflict when all three hold, as in ICAO's separation minima, where two
aircraft are separated once either the vertical or the horizontal minimum holds
([ICAO Doc 4444], ch. 5):

- their time windows overlap;
- their altitude bands are closer than the vertical minimum (the gap between the bands,
  negative when they overlap);
- their corridors are closer than the horizontal minimum: the distance between their
  segments, less both radii.

A pair is held to the larger of its two organisations' minima. The reported place is the
middle of the two segments' closest points, the reported time the start of the windows'
overlap: the first moment both drones may be there.

`Airspace` answers with a spatial index built once per check: the reserved legs that can
matter at all (window, bands and bounding box against the flight's own) are put into a
uniform grid, the flight's legs (their boxes widened by the largest reach) into the same
grid, and only pairs sharing a cell are measured, all with numpy. `first_conflict_pairwise`
is the plain definition, every pair in pure Python: the index must answer as it does.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .corridors import EARTH_RADIUS, Leg

MIN_CELL_M = 100.0
_KEY_SHIFT = 1 << 21


@dataclass(frozen=True)
class Reserved:
    """A reservation as the check needs it: whose, its legs (as stored: [lat0, lon0,
    lat1, lon1, low, high, t0, t1] each) and the minima it keeps."""

    key: str
    drone_id: str
    organisation_id: int
    legs: Sequence[Sequence[float]]
    radius_m: float
    horizontal_min_m: float
    vertical_min_m: float


@dataclass(frozen=True)
class Flight:
    """The corridors a flight asks for, and the minima its organisation keeps."""

    legs: Sequence[Leg]
    radius_m: float
    horizontal_min_m: float
    vertical_min_m: float


@dataclass(frozen=True)
class Clash:
    """A conflict: the flight's leg, the reservation met, where and when."""

    leg: int
    reserved: Reserved
    lat: float
    lon: float
    at: float  # seconds since the epoch
    distance_m: float  # between the corridors' edges
    band_gap_m: float
    # When the reserved leg's window closes: a flight that leaves later by a wait on the
    # ground is clear of this leg once its own leg's window opens after it.
    until: float = field(default=math.inf, compare=False)


class _Frame:
    """Local metres about an origin, on the flat earth (as onboard/envelope.py)."""

    def __init__(self, lat: float, lon: float) -> None:
        self.lat, self.lon = lat, lon
        self.k_north = math.radians(1.0) * EARTH_RADIUS
        self.k_east = self.k_north * math.cos(math.radians(lat))

    def xy(self, lat: np.ndarray | float, lon: np.ndarray | float) -> tuple:
        return (lon - self.lon) * self.k_east, (lat - self.lat) * self.k_north

    def latlon(self, x: float, y: float) -> tuple[float, float]:
        return self.lat + y / self.k_north, self.lon + x / self.k_east


@dataclass
class _Legs:
    """Legs as columns: x0 y0 x1 y1 low high t0 t1, and per leg its radius and minima."""

    x0: np.ndarray
    y0: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    low: np.ndarray
    high: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    radius: np.ndarray
    hmin: np.ndarray
    vmin: np.ndarray
    owner: np.ndarray

    @classmethod
    def build(cls, rows: np.ndarray, frame: _Frame, per_leg: np.ndarray, owner: np.ndarray):  # type: ignore[no-untyped-def]
        x0, y0 = frame.xy(rows[:, 0], rows[:, 1])
        x1, y1 = frame.xy(rows[:, 2], rows[:, 3])
        return cls(
            x0, y0, x1, y1, rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7],
            per_leg[:, 0], per_leg[:, 1], per_leg[:, 2], owner,
        )  # fmt: skip

    def take(self, mask: np.ndarray) -> _Legs:
        return _Legs(*(getattr(self, name)[mask] for name in self.__dataclass_fields__))

    def __len__(self) -> int:
        return len(self.t0)


def _rows(legs: Sequence[Leg]) -> np.ndarray:
    return np.array([leg.to_list() for leg in legs], dtype=float).reshape(-1, 8)


def _cross(ax, ay, bx, by):  # type: ignore[no-untyped-def]
    return ax * by - ay * bx


def _point_segment(px, py, ax, ay, bx, by):  # type: ignore[no-untyped-def]
    """Distance from p to segment ab, element-wise, and the closest point on ab."""
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    safe = np.where(length2 > 0, length2, 1.0)
    t = np.clip(((px - ax) * dx + (py - ay) * dy) / safe, 0.0, 1.0)
    t = np.where(length2 > 0, t, 0.0)
    cx, cy = ax + t * dx, ay + t * dy
    return np.hypot(px - cx, py - cy), cx, cy


def segment_distance(a: _Legs, b: _Legs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance between segments a[i] and b[i], and the middle of their closest points."""
    d1 = _cross(b.x1 - b.x0, b.y1 - b.y0, a.x0 - b.x0, a.y0 - b.y0)
    d2 = _cross(b.x1 - b.x0, b.y1 - b.y0, a.x1 - b.x0, a.y1 - b.y0)
    d3 = _cross(a.x1 - a.x0, a.y1 - a.y0, b.x0 - a.x0, b.y0 - a.y0)
    d4 = _cross(a.x1 - a.x0, a.y1 - a.y0, b.x1 - a.x0, b.y1 - a.y0)
    crossing = (d1 * d2 < 0) & (d3 * d4 < 0)
    options = [
        (*_point_segment(a.x0, a.y0, b.x0, b.y0, b.x1, b.y1), a.x0, a.y0),
        (*_point_segment(a.x1, a.y1, b.x0, b.y0, b.x1, b.y1), a.x1, a.y1),
        (*_point_segment(b.x0, b.y0, a.x0, a.y0, a.x1, a.y1), b.x0, b.y0),
        (*_point_segment(b.x1, b.y1, a.x0, a.y0, a.x1, a.y1), b.x1, b.y1),
    ]
    dist = np.stack([o[0] for o in options])
    best = np.argmin(dist, axis=0)
    pick = np.arange(len(best))
    mid_x = (
        np.stack([o[1] for o in options])[best, pick]
        + np.stack([o[3] for o in options])[best, pick]
    ) / 2
    mid_y = (
        np.stack([o[2] for o in options])[best, pick]
        + np.stack([o[4] for o in options])[best, pick]
    ) / 2
    # Crossing segments meet where a's parameter d1 / (d1 - d2) puts it.
    safe = np.where(crossing, d1 - d2, 1.0)
    u = np.where(crossing, d1 / safe, 0.0)
    mid_x = np.where(crossing, a.x0 + u * (a.x1 - a.x0), mid_x)
    mid_y = np.where(crossing, a.y0 + u * (a.y1 - a.y0), mid_y)
    return np.where(crossing, 0.0, dist[best, pick]), mid_x, mid_y


def _samples(legs: _Legs, spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along each leg no farther than `spacing` apart, both ends included:
    (x, y, leg position)."""
    length = np.hypot(legs.x1 - legs.x0, legs.y1 - legs.y0)
    counts = np.ceil(length / spacing).astype(np.int64) + 1
    leg = np.repeat(np.arange(len(legs)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    f = k / np.maximum(counts[leg] - 1, 1)
    x = legs.x0[leg] + f * (legs.x1[leg] - legs.x0[leg])
    y = legs.y0[leg] + f * (legs.y1[leg] - legs.y0[leg])
    return x, y, leg


def _key(cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
    return (cx + _KEY_SHIFT) * (2 * _KEY_SHIFT) + (cy + _KEY_SHIFT)


def _cells(legs: _Legs, widen: float, size: float) -> tuple[np.ndarray, np.ndarray]:
    """(cell key, leg position) of the cells within `widen` of each leg's sample points
    (half a cell apart); without widening, the cells the samples fall in.

    Sound for a pair within `reach`: a point of either leg is within a quarter cell of
    one of its samples, so with `widen = reach + size / 2` on one side the other side's
    sample's cell is among the widened ones."""
    x, y, leg = _samples(legs, size / 2)
    cx0 = np.floor((x - widen) / size).astype(np.int64)
    cx1 = np.floor((x + widen) / size).astype(np.int64)
    cy0 = np.floor((y - widen) / size).astype(np.int64)
    cy1 = np.floor((y + widen) / size).astype(np.int64)
    ny = cy1 - cy0 + 1
    counts = (cx1 - cx0 + 1) * ny
    point = np.repeat(np.arange(len(x)), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    keys = _key(cx0[point] + local // ny[point], cy0[point] + local % ny[point])
    return keys, leg[point]


def _pairs(flight: _Legs, reserved: _Legs, reach: float, size: float) -> tuple:
    """(flight leg, reserved leg) of every pair sharing a grid cell, once each."""
    fkeys, fleg = _cells(flight, reach + size / 2, size)
    fkeys, first = np.unique(fkeys * len(flight) + fleg, return_index=True)
    fkeys, fleg = fkeys // len(flight), fleg[first]
    rkeys, rleg = _cells(reserved, 0.0, size)
    # A leg sampled into one cell twice counts once.
    rkeys, first = np.unique(rkeys * len(reserved) + rleg, return_index=True)
    rkeys, rleg = rkeys // len(reserved), rleg[first]
    order = np.argsort(fkeys, kind="stable")
    fkeys, fleg = fkeys[order], fleg[order]
    lo = np.searchsorted(fkeys, rkeys, side="left")
    hi = np.searchsorted(fkeys, rkeys, side="right")
    counts = hi - lo
    r_of = np.repeat(rleg, counts)
    start = np.repeat(lo - (np.cumsum(counts) - counts), counts)
    f_of = fleg[start + np.arange(counts.sum())]
    unique = np.unique(f_of * len(reserved) + r_of)
    return unique // len(reserved), unique % len(reserved)


class Airspace:
    """The reserved corridors, ready to be checked against flights."""

    def __init__(self, reserved: Sequence[Reserved]) -> None:
        self.reserved = list(reserved)
        values = itertools.chain.from_iterable(leg for r in self.reserved for leg in r.legs)
        self._rows = np.fromiter(values, dtype=float).reshape(-1, 8)
        counts = [len(r.legs) for r in self.reserved]
        self._owner = np.repeat(np.arange(len(self.reserved)), counts)
        minima = np.array(
            [[r.radius_m, r.horizontal_min_m, r.vertical_min_m] for r in self.reserved]
        ).reshape(-1, 3)
        self._per_leg = minima[self._owner]

    def first_conflict(self, flight: Flight) -> Clash | None:
        """The flight's conflict that comes first in time, or None."""
        if not flight.legs or not len(self._rows):
            return None
        mine = _rows(flight.legs)
        frame = _Frame(mine[0, 0], mine[0, 1])
        ones = np.ones((len(mine), 1))
        own = np.hstack(
            [ones * flight.radius_m, ones * flight.horizontal_min_m, ones * flight.vertical_min_m]
        )
        a = _Legs.build(mine, frame, own, np.zeros(len(mine), dtype=int))
        b = self._near(a, _Legs.build(self._rows, frame, self._per_leg, self._owner))
        if not len(b):
            return None
        reach = (
            flight.radius_m
            + float(b.radius.max())
            + max(flight.horizontal_min_m, float(b.hmin.max()))
        )
        size = max(MIN_CELL_M, 2 * reach)
        i, j = _pairs(a, b, reach, size)
        return self._clash(a.take(i), b.take(j), i, frame)

    def around(self, flight: Flight) -> Airspace:
        """The reserved legs that may come within the minima of the flight's ground track at
        any time and height: a smaller airspace to check many variants of one flight
        against, its layers and its waits on the ground (airspace/separation.py)."""
        if not flight.legs or not len(self._rows):
            return self
        mine = _rows(flight.legs)
        frame = _Frame(mine[0, 0], mine[0, 1])
        ones = np.ones((len(mine), 1))
        own = np.hstack([ones * flight.radius_m, ones * flight.horizontal_min_m, ones * 0.0])
        a = _Legs.build(mine, frame, own, np.zeros(len(mine), dtype=int))
        b = _Legs.build(self._rows, frame, self._per_leg, np.arange(len(self._rows)))
        reach = (
            flight.radius_m
            + float(b.radius.max())
            + max(flight.horizontal_min_m, float(b.hmin.max()))
        )
        keep = np.minimum(b.x0, b.x1) < max(a.x0.max(), a.x1.max()) + reach
        keep &= np.maximum(b.x0, b.x1) > min(a.x0.min(), a.x1.min()) - reach
        keep &= np.minimum(b.y0, b.y1) < max(a.y0.max(), a.y1.max()) + reach
        keep &= np.maximum(b.y0, b.y1) > min(a.y0.min(), a.y1.min()) - reach
        near: dict[int, list] = {}
        for row in np.flatnonzero(keep):
            near.setdefault(int(self._owner[row]), []).append(self._rows[row].tolist())
        return Airspace(
            [dataclasses.replace(self.reserved[k], legs=legs) for k, legs in near.items()]
        )

    @staticmethod
    def _near(a: _Legs, b: _Legs) -> _Legs:
        """The reserved legs that may conflict with any of the flight's at all."""
        reach = (
            float(a.radius[0] + b.radius.max() + max(a.hmin[0], b.hmin.max())) if len(b) else 0.0
        )
        vreach = float(max(a.vmin[0], b.vmin.max())) if len(b) else 0.0
        keep = (b.t0 < a.t1.max()) & (b.t1 > a.t0.min())
        keep &= (b.low < a.high.max() + vreach) & (b.high > a.low.min() - vreach)
        keep &= np.minimum(b.x0, b.x1) < max(a.x0.max(), a.x1.max()) + reach
        keep &= np.maximum(b.x0, b.x1) > min(a.x0.min(), a.x1.min()) - reach
        keep &= np.minimum(b.y0, b.y1) < max(a.y0.max(), a.y1.max()) + reach
        keep &= np.maximum(b.y0, b.y1) > min(a.y0.min(), a.y1.min()) - reach
        return b.take(keep)

    def _clash(self, a: _Legs, b: _Legs, legs: np.ndarray, frame: _Frame) -> Clash | None:
        overlap = (a.t0 < b.t1) & (b.t0 < a.t1)
        gap = np.maximum(a.low, b.low) - np.minimum(a.high, b.high)
        close = overlap & (gap < np.maximum(a.vmin, b.vmin))
        a, b, legs, gap = a.take(close), b.take(close), legs[close], gap[close]
        if not len(a):
            return None
        distance, mid_x, mid_y = segment_distance(a, b)
        edge = distance - a.radius - b.radius
        hit = edge < np.maximum(a.hmin, b.hmin)
        if not hit.any():
            return None
        starts = np.where(hit, np.maximum(a.t0, b.t0), np.inf)
        k = int(np.argmin(starts))
        lat, lon = frame.latlon(float(mid_x[k]), float(mid_y[k]))
        reserved = self.reserved[int(b.owner[k])]
        return Clash(
            int(legs[k]), reserved, lat, lon, float(starts[k]), float(edge[k]), float(gap[k]),
            float(b.t1[k]),
        )  # fmt: skip


def first_conflict_pairwise(reserved: Sequence[Reserved], flight: Flight) -> Clash | None:
    """The same answer as `Airspace(reserved).first_conflict(flight)`, every pair in pure
    Python: the definition the index is measured and tested against."""
    if not flight.legs:
        return None
    frame = _Frame(flight.legs[0].lat0, flight.legs[0].lon0)
    best: Clash | None = None
    for i, mine in enumerate(flight.legs):
        for other in reserved:
            for values in other.legs:
                clash = _pair(frame, i, mine, flight, other, Leg.from_list(values))
                if clash is not None and (best is None or clash.at < best.at):
                    best = clash
    return best


def _pair(
    frame: _Frame, i: int, mine: Leg, flight: Flight, other: Reserved, leg: Leg
) -> Clash | None:
    if not (mine.t0 < leg.t1 and leg.t0 < mine.t1):
        return None
    gap = max(mine.low, leg.low) - min(mine.high, leg.high)
    if gap >= max(flight.vertical_min_m, other.vertical_min_m):
        return None
    a = [frame.xy(mine.lat0, mine.lon0), frame.xy(mine.lat1, mine.lon1)]
    b = [frame.xy(leg.lat0, leg.lon0), frame.xy(leg.lat1, leg.lon1)]
    distance, (mx, my) = _segments(a[0], a[1], b[0], b[1])
    edge = distance - flight.radius_m - other.radius_m
    if edge >= max(flight.horizontal_min_m, other.horizontal_min_m):
        return None
    lat, lon = frame.latlon(mx, my)
    return Clash(i, other, lat, lon, max(mine.t0, leg.t0), edge, gap, leg.t1)


def _closest(p: tuple, a: tuple, b: tuple) -> tuple[float, tuple[float, float]]:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = (
        0.0
        if length2 == 0
        else min(1.0, max(0.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2))
    )
    c = (a[0] + t * dx, a[1] + t * dy)
    return math.hypot(p[0] - c[0], p[1] - c[1]), c


def _segments(a0: tuple, a1: tuple, b0: tuple, b1: tuple) -> tuple[float, tuple[float, float]]:
    """Distance between segments a0a1 and b0b1 and the middle of their closest points."""

    def cross(o: tuple, p: tuple, q: tuple) -> float:
        return (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])

    d1, d2 = cross(b0, b1, a0), cross(b0, b1, a1)
    d3, d4 = cross(a0, a1, b0), cross(a0, a1, b1)
    if d1 * d2 < 0 and d3 * d4 < 0:
        u = d1 / (d1 - d2)
        return 0.0, (a0[0] + u * (a1[0] - a0[0]), a0[1] + u * (a1[1] - a0[1]))
    options = []
    for p, (s0, s1) in ((a0, (b0, b1)), (a1, (b0, b1)), (b0, (a0, a1)), (b1, (a0, a1))):
        distance, c = _closest(p, s0, s1)
        options.append((distance, ((p[0] + c[0]) / 2, (p[1] + c[1]) / 2)))
    return min(options, key=lambda o: o[0])

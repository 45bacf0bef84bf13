"""A mission's height profile over the terrain, for the planner to draw: the flight's
height above home and the ground under it (also above the ground at home), against the
distance flown over the ground.

The path is the one the envelope walks (terrain/guard.py mission_moves): take-off, legs
from target to target, landing. Each leg gets samples in proportion to its length (at
least its two ends); the ground is None where no terrain covers a sample or it is a void.

A sideways leg sent while a climb is under way (terrain/guard.py mission_climbs) is flown
on a slant: the profile also carries, for each such leg, the height the drone has surely
reached along it, least(d) = min(target, h0 + s·d) (terrain/climbout.py), as the corners
of that low edge, and its clearance held as the terrain check holds it — while least(d)
is less than the minimum above the ground the climb began over (home, for a take-off)
the drone climbs out and the terrain may not rise above that ground, from there least(d)
keeps the minimum above the terrain.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from onboard import envelope as env
from terrain.climbout import Climb, Paced
from terrain.guard import (
    CLIMB_OUT_TOLERANCE_M,
    _latlon,
    min_clearance,
    mission_climbs,
    mission_moves,
)
from terrain.lookup import LegClearance, Surface

# Samples in a whole profile: enough for a chart some hundreds of pixels wide.
SAMPLES = 400


def _vertices(home: Sequence[float], steps: Sequence[Mapping[str, Any]]) -> tuple[np.ndarray, list]:
    """The path's corners (NED from home, starting on the ground at home) and the step
    index that reaches each."""
    corners, indexes = [(0.0, 0.0, 0.0)], [None]
    for index, move, _start in mission_moves(home, steps, (0.0, 0.0, 0.0)):
        corners.append(move.ned)
        indexes.append(index)
    return np.array(corners, float), indexes


def _sampled(corners: np.ndarray, total: int) -> tuple[np.ndarray, np.ndarray]:
    """(points NED, distance over the ground) along the path, `total` samples shared by
    the legs in proportion to their horizontal length."""
    spans = np.hypot(np.diff(corners[:, 0]), np.diff(corners[:, 1]))
    length = float(spans.sum())
    points, along, done = [corners[:1]], [np.zeros(1)], 0.0
    for i, span in enumerate(spans.tolist()):
        count = max(1, math.ceil(total * span / length)) if length > 0 else 1
        fractions = np.linspace(0.0, 1.0, count + 1)[1:]
        points.append(corners[i] + (corners[i + 1] - corners[i]) * fractions[:, None])
        along.append(done + span * fractions)
        done += span
    return np.vstack(points), np.concatenate(along)


def _rounded(values: np.ndarray) -> list[float | None]:
    return [None if math.isnan(v) else round(v, 1) for v in values.tolist()]


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 1) + 0.0  # + 0.0: no -0.0


@dataclass(frozen=True)
class _SlantLeg:
    """A leg flown while a climb is under way: its step, its ends (NED from home), where
    it begins on the profile and the climb it flies out."""

    index: int
    start: np.ndarray
    end: np.ndarray
    from_m: float
    climb: Climb

    @property
    def length(self) -> float:
        return float(math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]))

    @property
    def target(self) -> float:
        return -float(self.end[2])

    def pieces(self, minimum: float, offset: float) -> list[tuple[float, float, bool]]:
        """The stretches (metres along) where the low edge is straight, as the terrain
        check cuts them: climbing out (True: less than the minimum above the ground the
        climb began over, `offset` metres below home, and below the target), climbing on
        to the target, level at it."""
        length, climb = self.length, self.climb
        out = min(length, climb.reaches(min(minimum - offset, self.target)))
        up = max(out, min(length, climb.reaches(self.target)))
        pieces = [(0.0, out, True), (out, up, False), (up, length, False)]
        return [p for p in pieces if p[1] - p[0] > env.MIN_LEG]

    def height(self, along: float, out: bool, offset: float) -> float:
        """The height above home a piece is sampled at: climbing out, the climb's ground
        (its clearance there is how far the terrain lies below that ground), else the low
        edge."""
        return -offset if out else self.climb.least(along, self.target)

    def point(self, along: float, height: float) -> np.ndarray:
        ned = self.start + (self.end - self.start) * (along / self.length)
        return np.array([ned[0], ned[1], -height])


def _climb_offset(
    surface: Surface, home: Sequence[float], home_ground: float, climb: Climb
) -> float:
    """How high home lies above the ground the climb began over (its `origin`, north and
    east of home; none: over home), where the terrain gives it: climbing out, the terrain
    may not rise above that ground."""
    origin = climb.origin
    if origin is None or math.hypot(*origin) < env.MIN_LEG:
        return 0.0
    lat, lon = env.ned_to_latlon(origin[0], origin[1], home)
    below = surface.elevation(lat, lon)
    return 0.0 if below is None else home_ground - below


def _piece_clearances(
    surface: Surface,
    home: Sequence[float],
    home_ground: float,
    leg: _SlantLeg,
    pieces: list,
    offset: float,
) -> list[LegClearance]:
    """Each piece's clearance above the terrain (its ends as latitude, longitude and
    altitude above sea level, sampled as terrain/guard.py samples them)."""
    ends = [[leg.point(d, leg.height(d, out, offset)) for d in (d0, d1)] for d0, d1, out in pieces]
    ned = np.array(ends, float).reshape(-1, 3)
    lla = np.column_stack((_latlon(ned, home), home_ground - ned[:, 2]))
    return surface.clearances(lla[0::2], lla[1::2], highest=False)


def _edge(leg: _SlantLeg, pieces: list) -> list[list[float]]:
    """The low edge's corners: [profile distance, height above home]."""
    corners = sorted({0.0, leg.length, *(p[1] for p in pieces)})
    return [[round(leg.from_m + d, 1), round(leg.climb.least(d, leg.target), 1)] for d in corners]


def _judged(pieces: list, found: list) -> tuple[float | None, float | None, float | None]:
    """(the terrain's highest rise above the climb's ground while climbing out, the lowest
    clearance after it, metres along the leg where that is); None where no terrain."""
    rise = lowest = at = None
    for (d0, _, out), piece in zip(pieces, found, strict=True):
        if piece is None or piece.minimum is None or piece.at is None:
            continue
        if out:
            rise = -piece.minimum if rise is None else max(rise, -piece.minimum)
        elif lowest is None or piece.minimum < lowest:
            lowest, at = piece.minimum, d0 + piece.at[2]
    return rise, lowest, at


def _slant(
    surface: Surface,
    home: Sequence[float],
    home_ground: float | None,
    minimum: float,
    leg: _SlantLeg,
) -> dict:
    """One leg flown while climbing: its low edge, the terrain's highest rise above the
    ground the climb began over (home for a take-off) while it climbs out, its lowest
    clearance from there on, and whether the terrain check refuses it (rule: the terrain
    may not rise above that ground while climbing out, the minimum holds from there)."""
    offset = 0.0 if home_ground is None else _climb_offset(surface, home, home_ground, leg.climb)
    pieces = leg.pieces(minimum, offset)
    found: list[LegClearance | None] = [None] * len(pieces)
    if home_ground is not None and pieces:
        found = list(_piece_clearances(surface, home, home_ground, leg, pieces, offset))
    rise, lowest, at = _judged(pieces, found)
    out_to = next((d1 for _, d1, out in pieces if out), None)
    refused = (rise is not None and rise > CLIMB_OUT_TOLERANCE_M) or (
        lowest is not None and lowest < minimum
    )
    return {
        "index": leg.index,
        "from_m": round(leg.from_m, 1),
        "to_m": round(leg.from_m + leg.length, 1),
        "level_m": [round(-float(leg.start[2]), 1), round(leg.target, 1)],
        "edge": _edge(leg, pieces),
        "climbing_out_to_m": None if out_to is None else round(leg.from_m + out_to, 1),
        "climb_out_rise_m": _round(rise),
        "lowest_clearance_m": _round(lowest),
        "lowest_at_m": None if at is None else _round(leg.from_m + at),
        "refused": bool(refused),
    }


def _slant_legs(
    corners: np.ndarray, indexes: list, corner_along: np.ndarray, climbs: Mapping
) -> list[_SlantLeg]:
    return [
        _SlantLeg(
            indexes[k], corners[k - 1], corners[k], float(corner_along[k - 1]), climbs[indexes[k]]
        )
        for k in range(1, len(corners))
        if indexes[k] in climbs
    ]


def profile(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    organisation_id: int | None = None,
    pace: Paced | None = None,
) -> dict | None:
    """The height profile of `steps` flown from the ground at `home`, or None without a
    home. `ground_m` is above the ground at home; `terrain` says whether any is known.
    `slants`: the legs flown while a climb is under way (at `pace`, the drone's; else the
    settings'), held to the organisation's minimum clearance (`minimum_clearance_m`)."""
    if home is None:
        return None
    corners, indexes = _vertices(home, steps)
    points, along = _sampled(corners, SAMPLES)
    latlon = _latlon(points, home)
    south, west = latlon.min(axis=0)
    north, east = latlon.max(axis=0)
    surface = Surface.covering(float(west), float(south), float(east), float(north))
    ground, _ = surface.sample(latlon[:, 0], latlon[:, 1])
    home_ground = surface.elevation(float(home[0]), float(home[1]))
    relative = ground - (home_ground if home_ground is not None else np.nan)
    corner_along = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(corners[:, 0]), np.diff(corners[:, 1])))))  # fmt: skip
    minimum = min_clearance(organisation_id)
    climbs = mission_climbs(home, steps, (0.0, 0.0, 0.0), pace)
    legs = _slant_legs(corners, indexes, corner_along, climbs)
    return {
        "terrain": home_ground is not None and bool(np.isfinite(relative).any()),
        "home_ground_m": None if home_ground is None else round(home_ground, 1),
        "minimum_clearance_m": minimum,
        "distance_m": [round(d, 1) for d in along.tolist()],
        "height_m": [round(-d, 1) for d in points[:, 2].tolist()],
        "ground_m": _rounded(relative),
        "steps": [
            {"index": i, "distance_m": round(float(d), 1), "height_m": round(-float(c[2]), 1)}
            for i, d, c in zip(indexes, corner_along, corners, strict=True)
            if i is not None
        ],
        "slants": [_slant(surface, home, home_ground, minimum, leg) for leg in legs],
    }

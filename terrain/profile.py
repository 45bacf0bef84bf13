"""A mission's height profile over the terrain, for the planner to draw: the flight's
height above home and the ground under it (also above the ground at home), against the
distance flown over the ground.

The path is the one the envelope walks (terrain/guard.py mission_moves): take-off, legs
from target to target, landing. Each leg gets samples in proportion to its length (at
least its two ends); the ground is None where no terrain covers a sample or it is a void.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from terrain.guard import _latlon, mission_moves
from terrain.lookup import Surface

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


def profile(home: Sequence[float] | None, steps: Sequence[Mapping[str, Any]]) -> dict | None:
    """The height profile of `steps` flown from the ground at `home`, or None without a
    home. `ground_m` is above the ground at home; `terrain` says whether any is known."""
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
    return {
        "terrain": home_ground is not None and bool(np.isfinite(relative).any()),
        "home_ground_m": None if home_ground is None else round(home_ground, 1),
        "distance_m": [round(d, 1) for d in along.tolist()],
        "height_m": [round(-d, 1) for d in points[:, 2].tolist()],
        "ground_m": _rounded(relative),
        "steps": [
            {"index": i, "distance_m": round(float(d), 1), "height_m": round(-float(c[2]), 1)}
            for i, d, c in zip(indexes, corner_along, corners, strict=True)
            if i is not None
        ],
    }

"""Areas built from exact metres on a local frame, so sizes reach the planner as clicked
vertices."""

from __future__ import annotations

import numpy as np

from missions.geo import LocalFrame

# The experiments of [Paula 2018] flew at the University of Aveiro campus.
AVEIRO = LocalFrame(40.6303, -8.6575)


def rectangle(
    east_m: float,
    north_m: float,
    *,
    origin: tuple[float, float] = (0.0, 0.0),
    frame: LocalFrame = AVEIRO,
) -> list[list[float]]:
    """Vertices A, B, C: A at `origin` (north, east metres), A→B east, B→C north."""
    n0, e0 = origin
    lat, lon = frame.to_latlon([n0, n0, n0 + north_m], [e0, e0 + east_m, e0 + east_m])
    return np.column_stack((lat, lon)).tolist()


def metres_between(a: list[float], b: list[float], frame: LocalFrame = AVEIRO) -> float:
    n, e = frame.to_ne([a[0], b[0]], [a[1], b[1]])
    return float(np.hypot(n[1] - n[0], e[1] - e[0]))


def point_at(north_m: float, east_m: float, frame: LocalFrame = AVEIRO) -> tuple[float, float]:
    return frame.point_to_latlon([north_m, east_m])

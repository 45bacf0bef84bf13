"""Which drones may join or replace a mission, on plain values.

A drone is available when it is online, not flying another mission and its battery is
above the reserve. Available drones are taken nearest first to where they are needed,
and between equally distant ones the fuller battery first.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from missions.geo import distance_m

DEFAULT_BATTERY_RESERVE = 0.3
# Two drones this close to each other count as equally far; battery then decides.
DISTANCE_RESOLUTION_M = 1.0


@dataclass(frozen=True)
class Candidate:
    drone_id: str
    online: bool
    in_mission: bool
    battery: float | None  # remaining, 0..1; None when the drone has not reported it
    position: tuple[float, float] | None  # (lat, lon); None before the first GPS fix


def is_available(candidate: Candidate, *, reserve: float = DEFAULT_BATTERY_RESERVE) -> bool:
    """Online, free and above the reserve; a drone that never reported a battery is not."""
    return (
        candidate.online
        and not candidate.in_mission
        and candidate.battery is not None
        and math.isfinite(candidate.battery)
        and candidate.battery > reserve
        and candidate.position is not None
    )


def select_drones(
    candidates: Sequence[Candidate],
    *,
    target: tuple[float, float],
    count: int,
    reserve: float = DEFAULT_BATTERY_RESERVE,
    exclude: Sequence[str] = (),
) -> list[Candidate]:
    """Up to `count` available drones, nearest to `target` first, then fuller battery first.

    `exclude` names drones that must not be chosen (e.g. the one being replaced). Fewer
    than `count` come back when fewer are available; the caller decides what that means.
    """
    if count < 0:
        raise ValueError("count must not be negative")
    excluded = set(exclude)
    usable = [
        c for c in candidates if c.drone_id not in excluded and is_available(c, reserve=reserve)
    ]
    if not usable or count == 0:
        return []
    lats = [c.position[0] for c in usable]  # type: ignore[index]
    lons = [c.position[1] for c in usable]  # type: ignore[index]
    distances = distance_m(lats, lons, target[0], target[1])
    ranked = sorted(
        zip(usable, distances.tolist(), strict=True),
        key=lambda pair: (
            round(pair[1] / DISTANCE_RESOLUTION_M),
            -(pair[0].battery or 0.0),
            pair[0].drone_id,
        ),
    )
    return [candidate for candidate, _ in ranked[:count]]

"""The minimum terrain clearance, as the ground's flight envelope check applies it.

Rule: every straight leg a drone flies sideways (`navigate`, `changeN`, `changeE`, and a
mission's legs from step to step) stays at least the organisation's minimum terrain
clearance (TerrainClearance, else TERRAIN_MIN_CLEARANCE: 30 m) above the terrain along its
whole length, its altitude taken as linear from one end to the other. A descent in place
(`altitude` down) must end at least that high above the terrain below. A take-off or a
climb moves away from the ground and is never refused; landing never is.

Heights are above home, and home is on the ground: the altitude above mean sea level of a
point is the terrain's elevation at home plus its height above home. Where the terrain
does not cover a leg (or home), or covers it with voids, that part is not checked (the
envelope's other limits still apply) and the check says so in a warning.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from django.conf import settings

from onboard import envelope as env
from terrain.lookup import LegClearance, Surface
from terrain.models import TerrainClearance, TerrainTile

TERRAIN_CLEARANCE = "terrain_clearance"
Walked = tuple[int | None, env.Move, env.NED | None]  # step index, move, the leg's start


@dataclass(frozen=True)
class TerrainViolation(env.Violation):
    """A leg or descent below the minimum clearance; `code` is the API's error code."""

    code: ClassVar[str] = TERRAIN_CLEARANCE
    clearance: float = 0.0
    minimum: float = 0.0


@dataclass
class Assessment:
    """What the terrain says of a mission's moves: refusals and warnings, by step."""

    violations: list[env.StepViolation] = field(default_factory=list)
    warnings: list[dict] = field(default_factory=list)

    @property
    def violation(self) -> env.Violation | None:
        return self.violations[0].violation if self.violations else None

    def warn(self, index: int | None, message: str, gaps: list | None = None) -> None:
        self.warnings.append({"step": index, "message": message, "gaps": gaps or []})


def has_terrain() -> bool:
    """Whether any terrain is imported: without any, every leg is flown as before."""
    return TerrainTile.objects.exists()


def min_clearance(organisation_id: int | None) -> float:
    """The organisation's minimum terrain clearance in metres."""
    found = TerrainClearance.objects.filter(organisation_id=organisation_id).values_list(
        "min_clearance", flat=True
    )
    value = next(iter(found), None)
    return float(settings.TERRAIN_MIN_CLEARANCE if value is None else value)


def _lla(ned: env.NED, home: Sequence[float], home_elevation: float) -> tuple[float, float, float]:
    lat, lon = env.ned_to_latlon(ned[0], ned[1], home)
    return lat, lon, home_elevation - ned[2]


def _latlon(ned: np.ndarray, home: Sequence[float]) -> np.ndarray:
    """Rows of (north, east, ...) metres from home → rows of (lat, lon), as
    onboard.envelope.ned_to_latlon does it."""
    lat = home[0] + np.degrees(ned[:, 0] / env.EARTH_RADIUS)
    across = env.EARTH_RADIUS * math.cos(math.radians(home[0]))
    return np.column_stack((lat, home[1] + np.degrees(ned[:, 1] / across)))


def _surface(home: Sequence[float], moves: Sequence[Walked]) -> Surface:
    """The grids under home and every move's ends."""
    ends = [m[1].ned for m in moves] + [m[2] for m in moves if m[2] is not None]
    points = np.vstack(([float(home[0]), float(home[1])], _latlon(np.array(ends, float), home)))
    (south, west), (north, east) = points.min(axis=0), points.max(axis=0)
    return Surface.covering(float(west), float(south), float(east), float(north))


def _is_leg(move: env.Move, start: env.NED | None) -> bool:
    if start is None or move.kind != "goto":
        return False
    return math.hypot(move.ned[0] - start[0], move.ned[1] - start[1]) >= env.MIN_LEG


def _leg_violation(found: LegClearance, minimum: float, legs: tuple) -> TerrainViolation | None:
    if found.minimum is None or found.minimum >= minimum or found.at is None:
        return None
    lat, lon, along = found.at
    side = "above" if found.minimum >= 0 else "below"
    return TerrainViolation(
        TERRAIN_CLEARANCE,
        f"The straight leg to the target passes {abs(found.minimum):.1f} m {side} the terrain "
        f"at ({lat:.5f}, {lon:.5f}), {along:.0f} m along it, below the minimum terrain "
        f"clearance of {minimum:g} m.",
        legs,
        clearance=round(found.minimum, 1),
        minimum=minimum,
    )


def _gap_warning(found: LegClearance) -> str:
    parts = ", ".join(f"{g.start_m:.0f}–{g.end_m:.0f} m ({g.reason})" for g in found.gaps)
    return (
        f"No terrain under part of the leg to the target ({parts} of {found.length_m:.0f} m): "
        "the terrain clearance is not checked there."
    )


def _descent_violation(
    surface: Surface, move: env.Move, start: env.NED | None, home: Sequence, home_elevation: float, minimum: float
) -> tuple[TerrainViolation | None, str | None]:  # fmt: skip
    """A descent in place ends at least `minimum` above the terrain; a climb is never refused."""
    if move.kind != "goto" or start is None or move.ned[2] <= start[2]:
        return None, None
    lat, lon, alt = _lla(move.ned, home, home_elevation)
    ground = surface.elevation(lat, lon)
    if ground is None:
        return None, "No terrain under the target of this descent: its clearance is not checked."
    if alt - ground >= minimum:
        return None, None
    message = (
        f"The target is {alt - ground:.1f} m above the terrain, below the minimum terrain "
        f"clearance of {minimum:g} m."
    )
    return TerrainViolation(TERRAIN_CLEARANCE, message, None, round(alt - ground, 1), minimum), None  # fmt: skip


@dataclass(frozen=True)
class _Ground:
    """The terrain under a plan and how heights above home meet it."""

    surface: Surface
    home: Sequence[float]
    home_elevation: float
    minimum: float

    def lla(self, ned: np.ndarray) -> np.ndarray:
        """Rows of NED from home → rows of latitude, longitude, altitude above sea level."""
        return np.column_stack((_latlon(ned, self.home), self.home_elevation - ned[:, 2]))


def _assess_leg(
    result: Assessment, ground: _Ground, index: int | None, ends: list, found: LegClearance
) -> None:
    """`ends`: the leg's start and end as [lat, lon, altitude]."""
    a, b = ends
    violation = _leg_violation(found, ground.minimum, ((a[0], a[1]), (b[0], b[1])))
    if not found.fully_covered:
        result.warn(index, _gap_warning(found), [g.to_dict() for g in found.gaps])
    if violation is not None:
        result.violations.append(env.StepViolation(index, violation))  # type: ignore[arg-type]


def _assess_descent(result: Assessment, ground: _Ground, walked: Walked) -> None:
    index, move, start = walked
    violation, warning = _descent_violation(
        ground.surface, move, start, ground.home, ground.home_elevation, ground.minimum
    )
    if warning:
        result.warn(index, warning)
    if violation is not None:
        result.violations.append(env.StepViolation(index, violation))  # type: ignore[arg-type]


def _assess_moves(result: Assessment, ground: _Ground, moves: Sequence[Walked]) -> None:
    """Every leg sampled in one pass (Surface.clearances), then each move in step order."""
    legs = [w for w in moves if _is_leg(w[1], w[2])]
    starts = ground.lla(np.array([w[2] for w in legs], float).reshape(-1, 3))
    ends = ground.lla(np.array([w[1].ned for w in legs], float).reshape(-1, 3))
    found = iter(ground.surface.clearances(starts, ends) if legs else [])
    pairs = iter(zip(starts.tolist(), ends.tolist(), strict=True))
    for walked in moves:
        if _is_leg(walked[1], walked[2]):
            _assess_leg(result, ground, walked[0], list(next(pairs)), next(found))
        else:
            _assess_descent(result, ground, walked)


def assess(
    organisation_id: int | None, home: Sequence[float] | None, moves: Iterable[Walked]
) -> Assessment:
    """Every move (step index, move, the leg's start in NED from home) held to the
    organisation's minimum terrain clearance."""
    result = Assessment()
    # A take-off climbs from the ground and a landing is never refused: only moves count.
    moves = [m for m in moves if m[1].kind == "goto"]
    if not moves:
        return result
    if home is None:
        result.warn(None, "Home is unknown: the terrain clearance is not checked.")
        return result
    surface = _surface(home, moves)
    home_elevation = surface.elevation(float(home[0]), float(home[1]))
    if home_elevation is None:
        result.warn(
            None,
            f"No terrain at home ({float(home[0]):.5f}, {float(home[1]):.5f}): heights above "
            "home cannot be compared with the terrain, so the terrain clearance is not checked.",
        )
        return result
    ground = _Ground(surface, home, home_elevation, min_clearance(organisation_id))
    _assess_moves(result, ground, moves)
    return result


def mission_moves(
    home: Sequence[float] | None, steps: Sequence[Mapping[str, Any]], start: env.NED | None
) -> list[Walked]:
    """A mission's moves flown from `start`, each leg from the previous target, as the
    envelope walks them (onboard.envelope.step_violations)."""
    moves: list[Walked] = []
    target = start
    for index, step in enumerate(steps):
        move = env.resolve(step["command"], step.get("params") or {}, target, target, home)
        if move is not None:
            moves.append((index, move, target))
            target = move.ned
    return moves


def step_violations(
    organisation_id: int | None,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
) -> list[env.StepViolation]:
    """Every step of a mission flown from `start` that comes below the minimum clearance."""
    return assess(organisation_id, home, mission_moves(home, steps, start)).violations


def plan_warnings(
    organisation_id: int | None,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
) -> list[dict]:
    """Where a mission's terrain clearance could not be checked, step by step."""
    return assess(organisation_id, home, mission_moves(home, steps, start)).warnings


def move_assessment(
    organisation_id: int | None, home: Sequence[float] | None, start: env.NED | None, move: env.Move
) -> Assessment:
    """The terrain's refusal (`violation`) and warnings of one command's move from `start`
    (its current target)."""
    return assess(organisation_id, home, [(None, move, start)])

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


def _surface(home: Sequence[float], moves: Sequence[Walked]) -> Surface:
    points = [(float(home[0]), float(home[1]))]
    for _, move, start in moves:
        points.append(env.ned_to_latlon(move.ned[0], move.ned[1], home))
        if start is not None:
            points.append(env.ned_to_latlon(start[0], start[1], home))
    lats, lons = [p[0] for p in points], [p[1] for p in points]
    return Surface.covering(min(lons), min(lats), max(lons), max(lats))


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


def _assess_move(
    result: Assessment, surface: Surface, walked: Walked, home: Sequence, home_elevation: float, minimum: float
) -> None:  # fmt: skip
    index, move, start = walked
    gaps = None
    if not _is_leg(move, start):
        violation, warning = _descent_violation(surface, move, start, home, home_elevation, minimum)
    else:
        a, b = _lla(start, home, home_elevation), _lla(move.ned, home, home_elevation)  # type: ignore[arg-type]
        found = surface.clearance_along(a, b)
        violation = _leg_violation(found, minimum, ((a[0], a[1]), (b[0], b[1])))
        warning = None if found.fully_covered else _gap_warning(found)
        gaps = [g.to_dict() for g in found.gaps]
    if warning:
        result.warn(index, warning, gaps)
    if violation is not None:
        result.violations.append(env.StepViolation(index, violation))  # type: ignore[arg-type]


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
    minimum = min_clearance(organisation_id)
    for walked in moves:
        _assess_move(result, surface, walked, home, home_elevation, minimum)
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

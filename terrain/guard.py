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

Ceiling above the terrain: an organisation that reads its envelope's maximum height above
the terrain (TerrainClearance.ceiling_above_terrain, else TERRAIN_CEILING_ABOVE_TERRAIN)
also holds every point of every leg, and the target of a climb in place, to at most the
drone's maximum height above the terrain beneath it, wherever the terrain is known. A leg
that starts higher above the terrain than that (the ground fell away under a hovering
drone) may go on at up to the height above the terrain it starts at, so a drone can
always fly on or down. The maximum height above home still holds as well: the drone
applies that one itself and has no terrain. The minimum height above the terrain is the
minimum terrain clearance above.
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
MAX_HEIGHT_AGL = "max_height_agl"
# Rounding of heights between the ground's walk and the samples: a leg flown exactly at
# the ceiling is not refused for a centimetre.
CEILING_TOLERANCE_M = 0.05
Walked = tuple[int | None, env.Move, env.NED | None]  # step index, move, the leg's start


@dataclass(frozen=True)
class TerrainViolation(env.Violation):
    """A leg or descent below the minimum clearance; `code` is the API's error code."""

    code: ClassVar[str] = TERRAIN_CLEARANCE
    clearance: float = 0.0
    minimum: float = 0.0


@dataclass(frozen=True)
class CeilingViolation(env.Violation):
    """A leg or climb higher above the terrain than the envelope's maximum height: the
    envelope's own refusal (409 `outside_envelope`)."""

    height: float = 0.0
    ceiling: float = 0.0


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
    return terrain_rules(organisation_id)[0]


def terrain_rules(organisation_id: int | None) -> tuple[float, bool]:
    """The organisation's minimum terrain clearance (m) and whether its envelope's maximum
    height is read above the terrain."""
    found = TerrainClearance.objects.filter(organisation_id=organisation_id).values_list(
        "min_clearance", "ceiling_above_terrain"
    )
    row = next(iter(found), None)
    if row is None:
        return float(settings.TERRAIN_MIN_CLEARANCE), bool(settings.TERRAIN_CEILING_ABOVE_TERRAIN)
    return float(row[0]), bool(row[1])


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


def _ceiling_leg_violation(
    found: LegClearance, ceiling: float, legs: tuple
) -> CeilingViolation | None:
    """Above the ceiling somewhere along the leg, and higher there than at its start."""
    if found.highest is None or found.highest_at is None:
        return None
    allowed = max(ceiling, found.at_start if found.at_start is not None else -math.inf)
    if found.highest <= allowed + CEILING_TOLERANCE_M:
        return None
    lat, lon, along = found.highest_at
    return CeilingViolation(
        MAX_HEIGHT_AGL,
        f"The straight leg to the target rises to {found.highest:.1f} m above the terrain at "
        f"({lat:.5f}, {lon:.5f}), {along:.0f} m along it, above the envelope's maximum "
        f"height of {ceiling:g} m above the terrain.",
        legs,
        height=round(found.highest, 1),
        ceiling=ceiling,
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
    ceiling: float | None = None  # the maximum height above the terrain, when applied

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
    if ground.ceiling is not None:
        above = _ceiling_leg_violation(found, ground.ceiling, ((a[0], a[1]), (b[0], b[1])))
        if above is not None:
            result.violations.append(env.StepViolation(index, above))  # type: ignore[arg-type]


def _climb_violation(ground: _Ground, move: env.Move, start: env.NED | None) -> CeilingViolation | None:  # fmt: skip
    """A climb in place ends at most the ceiling above the terrain below."""
    if ground.ceiling is None or start is None or move.ned[2] >= start[2]:
        return None
    lat, lon, alt = _lla(move.ned, ground.home, ground.home_elevation)
    below = ground.surface.elevation(lat, lon)
    if below is None or alt - below <= ground.ceiling + CEILING_TOLERANCE_M:
        return None
    return CeilingViolation(
        MAX_HEIGHT_AGL,
        f"The target is {alt - below:.1f} m above the terrain, above the envelope's maximum "
        f"height of {ground.ceiling:g} m above the terrain.",
        None,
        height=round(alt - below, 1),
        ceiling=ground.ceiling,
    )


def _assess_descent(result: Assessment, ground: _Ground, walked: Walked) -> None:
    index, move, start = walked
    climb = _climb_violation(ground, move, start)
    if climb is not None:
        result.violations.append(env.StepViolation(index, climb))  # type: ignore[arg-type]
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
    highest = ground.ceiling is not None  # the ceiling above the terrain wants the tops
    found = iter(ground.surface.clearances(starts, ends, highest=highest) if legs else [])
    pairs = iter(zip(starts.tolist(), ends.tolist(), strict=True))
    for walked in moves:
        if _is_leg(walked[1], walked[2]):
            _assess_leg(result, ground, walked[0], list(next(pairs)), next(found))
        else:
            _assess_descent(result, ground, walked)


def assess(
    organisation_id: int | None,
    home: Sequence[float] | None,
    moves: Iterable[Walked],
    ceiling: float | None = None,
) -> Assessment:
    """Every move (step index, move, the leg's start in NED from home) held to the
    organisation's minimum terrain clearance, and to `ceiling` (the drone's maximum
    height) above the terrain where the organisation reads its ceiling there."""
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
    minimum, above_terrain = terrain_rules(organisation_id)
    ground = _Ground(surface, home, home_elevation, minimum, ceiling if above_terrain else None)
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
    ceiling: float | None = None,
) -> list[env.StepViolation]:
    """Every step of a mission flown from `start` that comes below the minimum clearance
    (or above `ceiling` over the terrain, where the organisation reads it so)."""
    return assess(organisation_id, home, mission_moves(home, steps, start), ceiling).violations


def plan_warnings(
    organisation_id: int | None,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
) -> list[dict]:
    """Where a mission's terrain clearance could not be checked, step by step."""
    return assess(organisation_id, home, mission_moves(home, steps, start)).warnings


def move_assessment(
    organisation_id: int | None,
    home: Sequence[float] | None,
    start: env.NED | None,
    move: env.Move,
    ceiling: float | None = None,
) -> Assessment:
    """The terrain's refusal (`violation`) and warnings of one command's move from `start`
    (its current target)."""
    return assess(organisation_id, home, [(None, move, start)], ceiling)

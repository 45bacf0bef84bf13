"""The minimum terrain clearance, as the ground's flight envelope check applies it.

Rule: every straight leg a drone flies sideways (`navigate`, `changeN`, `changeE`, and a
mission's legs from step to step) stays at least the organisation's minimum terrain
clearance (TerrainClearance, else TERRAIN_MIN_CLEARANCE: 30 m) above the terrain along its
whole length, its altitude taken as linear from one end to the other. A descent in place
(`altitude` down) must end at least that high above the terrain below. A take-off or a
climb moves away from the ground and is never refused; landing never is.

Climb-out: a sideways leg sent while a take-off or a climb is still under way (no
`wait_for_flight` between them; for a command, and for the first leg of a mission
started, a drone still climbing to its last target) is flown on a slant from the height the drone is at, and is checked against the
height it has surely reached at each point, least(d) = min(target, h0 + s·d)
(terrain/climbout.py), not against the straight line from the climb's target. While
the drone is less than the minimum clearance above the ground the climb began over
(home's for a take-off at home; elsewhere the ground under the climb, home's where the
terrain does not give it) and below the leg's target, it is climbing out: it must be at
least as high above the terrain as above that ground, i.e. the terrain may not rise
above it. From there the minimum holds as on any leg: a leg whose
target is below the minimum is refused whether it waits for its climb or not. The ceiling
above the terrain is still held on the straight line at the target's height, the highest
the drone can be.

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
from terrain.climbout import Climb, Paced, climb_slope, slowest_climb
from terrain.lookup import LegClearance, Surface
from terrain.models import TerrainClearance, TerrainTile

TERRAIN_CLEARANCE = "terrain_clearance"
MAX_HEIGHT_AGL = "max_height_agl"
# Rounding of heights between the ground's walk and the samples: a leg flown exactly at
# the ceiling is not refused for a centimetre.
CEILING_TOLERANCE_M = 0.05
# The same rounding for the climb-out rule: terrain level with home is not above it for
# the bilinear interpolation's last bits.
CLIMB_OUT_TOLERANCE_M = 0.05
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
    result: Assessment,
    ground: _Ground,
    index: int | None,
    ends: list,
    found: LegClearance,
    climb: Climb | None = None,
) -> None:
    """`ends`: the leg's start and end as [lat, lon, altitude]; `climb`: the climb under
    way when it is flown on a slant."""
    a, b = ends
    legs = ((a[0], a[1]), (b[0], b[1]))
    if climb is None:
        violation = _leg_violation(found, ground.minimum, legs)
    else:
        violation = _slant_violation(ground, ends, found.length_m, climb, legs)
    if not found.fully_covered:
        result.warn(index, _gap_warning(found), [g.to_dict() for g in found.gaps])
    if violation is not None:
        result.violations.append(env.StepViolation(index, violation))  # type: ignore[arg-type]
    if ground.ceiling is not None:
        above = _ceiling_leg_violation(found, ground.ceiling, ((a[0], a[1]), (b[0], b[1])))
        if above is not None:
            result.violations.append(env.StepViolation(index, above))  # type: ignore[arg-type]


def _slant_pieces(
    ground: _Ground, length: float, climb: Climb, target: float, offset: float
) -> list[tuple[float, float, bool]]:
    """The stretches (metres along the leg) where least(d) is a straight line: climbing
    out (True: less than the minimum above the ground the climb began over, `offset`
    metres below home, and below the target), climbing on to the target, level."""
    out = min(length, climb.reaches(min(ground.minimum - offset, target)))
    up = max(out, min(length, climb.reaches(target)))
    pieces = [(0.0, out, True), (out, up, False), (up, length, False)]
    return [p for p in pieces if p[1] - p[0] > env.MIN_LEG]


def _over_home(climb: Climb) -> bool:
    return climb.origin is None or math.hypot(*climb.origin) < env.MIN_LEG


def _climb_ground(ground: _Ground, climb: Climb) -> float:
    """The elevation (m above sea level) of the ground the climb began over, which the
    terrain may not rise above while climbing out: home's for a climb over home, and
    where the terrain does not give it there."""
    if _over_home(climb):
        return ground.home_elevation
    lat, lon = env.ned_to_latlon(climb.origin[0], climb.origin[1], ground.home)
    below = ground.surface.elevation(lat, lon)
    return ground.home_elevation if below is None else below


def _slant_violation(
    ground: _Ground, ends: list, length: float, climb: Climb, legs: tuple
) -> TerrainViolation | None:
    """The first place along a leg flown while climbing where the drone, at the height
    it has surely reached, breaks the climb-out rule or the minimum clearance."""
    a, b = np.array(ends[0], float), np.array(ends[1], float)
    target = b[2] - ground.home_elevation
    reference = _climb_ground(ground, climb)
    offset = ground.home_elevation - reference  # home's height above the climb's ground
    pieces = _slant_pieces(ground, length, climb, target, offset)
    starts: list[list[float]] = []
    stops: list[list[float]] = []
    for d0, d1, out in pieces:
        for d, points in ((d0, starts), (d1, stops)):
            point = a + (b - a) * (d / length)
            # Climbing out, the leg is sampled at the elevation of the climb's ground: its
            # clearance there is how far the terrain lies below that ground.
            height = -offset if out else climb.least(d, target)
            points.append([point[0], point[1], ground.home_elevation + height])
    found = ground.surface.clearances(np.array(starts), np.array(stops), highest=False)
    for (d0, _, out), piece in zip(pieces, found, strict=True):
        if piece.minimum is None or piece.at is None:
            continue
        lat, lon, along = piece.at[0], piece.at[1], d0 + piece.at[2]
        least = climb.least(along, target)
        if out and piece.minimum < -CLIMB_OUT_TOLERANCE_M:
            above = least + offset  # the height above the climb's ground
            return _climb_out_violation((lat, lon, along), least, above, -piece.minimum, climb, legs)  # fmt: skip
        if not out and piece.minimum < ground.minimum:
            return _climbing_violation((lat, lon, along), least, piece.minimum, ground, legs)
    return None


def _climb_out_violation(
    at: tuple[float, float, float],
    least: float,
    above: float,
    rise: float,
    climb: Climb,
    legs: tuple,
) -> TerrainViolation:
    """`above`: the height over the climb's ground; `rise`: the terrain's above it."""
    lat, lon, along = at
    home = _over_home(climb)
    ground = "home's elevation" if home else "the ground the climb began over"
    limit = "home" if home else "the ground the climb began over"
    return TerrainViolation(
        TERRAIN_CLEARANCE,
        f"The leg to the target is flown while the drone is still climbing out of its "
        f"take-off: {along:.0f} m along it, at ({lat:.5f}, {lon:.5f}), it is surely only "
        f"{least:.1f} m above home, and the terrain there rises {rise:.1f} m above {ground}, "
        f"leaving {above - rise:.1f} m of clearance; below the minimum terrain clearance the "
        f"terrain may not rise above {limit}.",
        legs,
        clearance=round(above - rise, 1),
        minimum=round(above, 1),
    )


def _climbing_violation(
    at: tuple[float, float, float], least: float, clearance: float, ground: _Ground, legs: tuple
) -> TerrainViolation:
    lat, lon, along = at
    side = "above" if clearance >= 0 else "below"
    return TerrainViolation(
        TERRAIN_CLEARANCE,
        f"The leg to the target is flown while the drone is still climbing: {along:.0f} m "
        f"along it, at ({lat:.5f}, {lon:.5f}), it is surely only {least:.1f} m above home, "
        f"{abs(clearance):.1f} m {side} the terrain, below the minimum terrain clearance of "
        f"{ground.minimum:g} m.",
        legs,
        clearance=round(clearance, 1),
        minimum=ground.minimum,
    )


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


def _assess_moves(
    result: Assessment,
    ground: _Ground,
    moves: Sequence[Walked],
    climbs: Mapping[Any, Climb],
) -> None:
    """Every leg sampled in one pass (Surface.clearances), then each move in step order;
    a leg flown while a climb is under way (`climbs`, by step) is sampled on its slant."""
    legs = [w for w in moves if _is_leg(w[1], w[2])]
    starts = ground.lla(np.array([w[2] for w in legs], float).reshape(-1, 3))
    ends = ground.lla(np.array([w[1].ned for w in legs], float).reshape(-1, 3))
    highest = ground.ceiling is not None  # the ceiling above the terrain wants the tops
    found = iter(ground.surface.clearances(starts, ends, highest=highest) if legs else [])
    pairs = iter(zip(starts.tolist(), ends.tolist(), strict=True))
    for walked in moves:
        if _is_leg(walked[1], walked[2]):
            pair, leg = list(next(pairs)), next(found)
            climb = climbs.get((walked[0], walked[2]), climbs.get(walked[0]))
            _assess_leg(result, ground, walked[0], pair, leg, climb)
        else:
            _assess_descent(result, ground, walked)


def assess(
    organisation_id: int | None,
    home: Sequence[float] | None,
    moves: Iterable[Walked],
    ceiling: float | None = None,
    climbs: Mapping[Any, Climb] | None = None,
) -> Assessment:
    """Every move (step index, move, the leg's start in NED from home) held to the
    organisation's minimum terrain clearance, and to `ceiling` (the drone's maximum
    height) above the terrain where the organisation reads its ceiling there. `climbs`:
    the legs flown while a climb is under way, by step index (None: a command's), or by
    (step index, the leg's start) for one leg of a step."""
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
    _assess_moves(result, ground, moves, climbs or {})
    return result


def mission_moves(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
    shortcuts: bool = False,
) -> list[Walked]:
    """A mission's moves flown from `start` as the envelope walks them (onboard/envelope.py
    `walk`), each leg from the previous target; `shortcuts`: with the legs of a move sent
    before the earlier ones ended (its fan legs, with the step's index and move), as the
    clearance checks them; without, the path as drawn."""
    walked = env.walk(home, steps, start, False, shortcuts)
    return [(index, move, leg) for index, move, leg, _ in walked]


@dataclass(frozen=True)
class SettingsPace:
    """The pace of a drone whose gear states no speed (airspace/reservations.py pace_for
    builds its Pace from the same settings): for a plan no drone flies yet."""

    speed_m_s: float = field(default_factory=lambda: float(settings.AIRSPACE_CRUISE_SPEED_M_S))
    climb_m_s: float = field(default_factory=lambda: float(settings.AIRSPACE_CLIMB_SPEED_M_S))
    slack: float = field(default_factory=lambda: float(settings.AIRSPACE_TIME_SLACK))
    early: float = field(default_factory=lambda: float(settings.AIRSPACE_TIME_EARLY))


def _height(target: env.NED | None) -> float:
    return 0.0 if target is None else -target[2]


def _after_sleep(surely: float | None, seconds: float, target: float, pace: Paced) -> float | None:
    """A sleep is flown climbing: the climb is surely done once its slowest climb is."""
    if surely is None:
        return None
    surely += seconds * slowest_climb(pace)
    return None if surely >= target else surely


def mission_climbs(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
    pace: Paced | None = None,
    climbing_from: float | None = None,
) -> dict[int | None, Climb]:
    """The legs of a mission flown while a climb is under way, by step index: a take-off
    or a climb in place stays under way until a `wait_for_flight`, a landing or the next
    sideways leg, which flies it out on a slant (terrain/climbout.py). `climbing_from`:
    the height of a drone still climbing to `start` (fleet/envelopes.py rise_under_way)
    when the mission starts: its first leg flies that climb out."""
    pace = pace or SettingsPace()
    climbs: dict[int | None, Climb] = {}
    surely = climbing_from  # the height surely reached while a climb is under way
    origin = None if start is None else (start[0], start[1])  # where that climb began
    target = start
    for index, step in enumerate(steps):
        command, params = step["command"], step.get("params") or {}
        if command == "wait_for_flight":
            surely = None
        elif command == "sleep":
            surely = _after_sleep(surely, float(params.get("value", 0.0)), _height(target), pace)
        move = env.resolve(command, params, target, target, home)
        if move is None:
            continue
        if _is_leg(move, target):
            if surely is not None:
                speed = params.get("speed")
                climbs[index] = Climb(surely, climb_slope(pace, speed and float(speed)), origin)
            surely = None
        elif move.kind == "land":
            surely = None
        else:  # a take-off or a move in place: climbing on from where it surely is
            if surely is None:
                origin = (move.ned[0], move.ned[1])
            base = _height(target) if surely is None else surely
            surely = base if -move.ned[2] > base else None
        target = move.ned
    return climbs


def step_violations(
    organisation_id: int | None,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
    ceiling: float | None = None,
    pace: Paced | None = None,
    climbing_from: float | None = None,
) -> list[env.StepViolation]:
    """Every step of a mission flown from `start` that comes below the minimum clearance
    (or above `ceiling` over the terrain, where the organisation reads it so); `pace`: the
    drone's (airspace/reservations.py pace_for), for its legs flown while climbing;
    `climbing_from`: the height of a drone still climbing to `start` (mission_climbs)."""
    moves = mission_moves(home, steps, start, shortcuts=True)
    climbs = leg_climbs(home, steps, start, moves, pace, climbing_from)
    return _first_per_step(assess(organisation_id, home, moves, ceiling, climbs).violations)


def leg_climbs(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
    moves: Sequence[Walked],
    pace: Paced | None = None,
    climbing_from: float | None = None,
) -> dict[Any, Climb]:
    """The climbs the walked `moves` are flown on: by step index for a step's planned leg
    (mission_climbs), by (step index, the leg's start) for a fan leg (_fan_climbs)."""
    climbs: dict[Any, Climb] = dict(mission_climbs(home, steps, start, pace, climbing_from))
    climbs.update(_fan_climbs(moves, steps, climbs, pace or SettingsPace()))
    return climbs


def _fan_climbs(
    moves: Sequence[Walked],
    steps: Sequence[Mapping[str, Any]],
    climbs: Mapping[Any, Climb],
    pace: Paced,
) -> dict[tuple[int | None, env.NED], Climb]:
    """The climbs of a step's fan legs (every leg of a step after its planned one) that
    start lower than their target: sent before the moves they cut across ended, they leave
    from wherever the drone is there and climb on at least at its slowest, as on a slant
    from that point (the step's own climb, where it has one, from no higher)."""
    found: dict[tuple[int | None, env.NED], Climb] = {}
    planned: set[int | None] = set()
    for index, move, start in moves:
        if index not in planned or start is None:
            planned.add(index)
            continue
        if -start[2] >= -move.ned[2]:
            continue  # level or going down: the straight line holds
        step = climbs.get(index)
        speed = (steps[index].get("params") or {}).get("speed") if index is not None else None
        slope = step.slope if step else climb_slope(pace, speed and float(speed))
        height = min(-start[2], step.start) if step else -start[2]
        found[(index, start)] = Climb(height, slope, (start[0], start[1]))
    return found


def _first_per_step(found: list[env.StepViolation]) -> list[env.StepViolation]:
    """One refusal of each kind per step: its planned leg's, else its first fan leg's."""
    seen: set[tuple[int | None, type]] = set()
    kept = []
    for item in found:
        key = (item.index, type(item.violation))
        if key not in seen:
            seen.add(key)
            kept.append(item)
    return kept


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
    climb: Climb | None = None,
) -> Assessment:
    """The terrain's refusal (`violation`) and warnings of one command's move from `start`
    (its current target); `climb`: the climb under way when it is sent, from the drone's
    current height."""
    climbs: dict[int | None, Climb] = {} if climb is None else {None: climb}
    return assess(organisation_id, home, [(None, move, start)], ceiling, climbs)

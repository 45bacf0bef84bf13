"""A coverage mission flown at a constant height above the terrain (terrain/following.py):
the spec's `terrain_following` object → the mission's steps and the home they are placed
from.

`{"home": [lat, lon], "tolerance_m": 10, "speed_m_s": 5, "climb_m_s": 2, "descent_m_s": 1}`:
the mission's `altitude` is then the height above the ground, everywhere; heights are
placed above the ground at `home`, which becomes the mission's plan home (a drone taking
off elsewhere is checked from there).

Every leg is flown at a set speed (the agent paces its target along the leg), slowed so
that its climb or descent stays within the climb and descent rates: a drone whose
vertical speed lags its horizontal one would fly into a rising slope. The defaults are
below ArduCopter's WPNAV_SPEED_UP (2.5 m/s) and WPNAV_SPEED_DN (1.5 m/s) [ArduPilot
parameters] and at PX4's MPC_Z_VEL_MAX_DN (1 m/s) [PX4 parameters].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import terrain
from missions import planning
from missions.errors import MissionError
from onboard.envelope import latlon_to_ne
from terrain.following import DEFAULT_TOLERANCE_M, FollowingError, follow

FIELD = "terrain_following"
CLIMB_M_S = 2.0
DESCENT_M_S = 1.0
# The agent's pace floor (docs/protocol.md: `speed` 0.1 to 50 m/s).
MIN_SPEED_M_S = 0.1
MAX_SPEED_M_S = 50.0


def _number(value: dict, name: str, default: float, lo: float, hi: float) -> float:
    number = value.get(name, default)
    if isinstance(number, bool) or not isinstance(number, int | float) or not lo <= number <= hi:
        raise planning.PlanningError(f"{FIELD}.{name}", f"must be a number from {lo:g} to {hi:g}")
    return float(number)


def _spec(
    value: Any, speed: float
) -> tuple[tuple[float, float], float, tuple[float, float, float]]:
    """(home, tolerance, (speed, climb, descent)) from the spec."""
    if not isinstance(value, dict):
        raise planning.PlanningError(FIELD, 'must be an object: {"home": [lat, lon], "tolerance_m": 10}')  # fmt: skip
    home = planning.parse_point(value.get("home"), f"{FIELD}.home")
    tolerance = value.get("tolerance_m", DEFAULT_TOLERANCE_M)
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float):
        raise planning.PlanningError(f"{FIELD}.tolerance_m", "must be a number of metres")
    rates = (
        _number(value, "speed_m_s", speed, MIN_SPEED_M_S, MAX_SPEED_M_S),
        _number(value, "climb_m_s", CLIMB_M_S, MIN_SPEED_M_S, MAX_SPEED_M_S),
        _number(value, "descent_m_s", DESCENT_M_S, MIN_SPEED_M_S, MAX_SPEED_M_S),
    )
    return home, float(tolerance), rates


def _paced(points: list, home: Sequence[float], altitude: float, rates: tuple) -> list:
    """Each point with the speed of the leg that ends there: the cruise speed, or slower
    where the leg climbs or descends faster than the rates allow."""
    cruise, climb, descent = rates
    rows, last, height = [], (float(home[0]), float(home[1])), altitude
    for p in points:
        across = math.hypot(*latlon_to_ne(p.lat, p.lon, last))
        rise = p.height - height
        rate = climb if rise > 0 else descent
        speed = (
            cruise
            if rise == 0
            else min(cruise, max(MIN_SPEED_M_S, rate * math.hypot(across, rise) / abs(rise)))
        )
        rows.append((p.lat, p.lon, p.height, p.waypoint, speed))
        last, height = (p.lat, p.lon), p.height
    return rows


def followed_points(
    spec: Any,
    waypoints: Sequence[Sequence[float]],
    altitude: float,
    max_points: int,
    speed: float,
) -> tuple[list, tuple[float, float], float]:
    """(points, home, tolerance): the waypoints and the points added between them, each
    (lat, lon, height above home, is a waypoint, speed of the leg to it); `speed` is the
    cruise speed unless the spec gives one. Raises planning.PlanningError."""
    home, tolerance, rates = _spec(spec, speed)
    try:
        points = follow(home, waypoints, altitude, tolerance)
    except FollowingError as exc:
        field = exc.field if exc.field == FIELD else f"{FIELD}.{exc.field}"
        raise planning.PlanningError(field, exc.message) from None
    if len(points) > max_points:
        raise planning.PlanningError(FIELD, f"following the terrain needs {len(points)} points, more than the limit of {max_points}; raise the tolerance or plan a smaller area")  # fmt: skip
    return _paced(points, home, altitude, rates), home, tolerance


def coverage_steps(
    spec: Any,
    waypoints: Sequence[Sequence[float]],
    altitude: float,
    action: Any,
    max_points: int,
    speed: float,
) -> tuple[list[dict], list[float], dict]:
    """The steps of a terrain-following coverage, its plan home and what to keep of it."""
    rows, home, tolerance = followed_points(spec, waypoints, altitude, max_points, speed)
    steps = planning.followed_steps(rows, altitude=altitude, intermediate_action=action)
    kept = {"home": list(home), "tolerance_m": tolerance, "height_agl_m": altitude}
    return steps, list(home), kept


def followed_body(
    spec: Any,
    waypoints: Sequence[Sequence[float]],
    altitude: float,
    max_points: int,
    speed: float,
) -> list[dict]:
    """The planner's view of a terrain-following path: each point with its height above
    home and the speed of the leg to it."""
    rows, _home, _tolerance = followed_points(spec, waypoints, altitude, max_points, speed)
    keys = ("lat", "lon", "height_m", "waypoint", "speed_m_s")
    return [
        dict(zip(keys, (lat, lon, round(h, 3), w, round(v, 2)), strict=True))
        for lat, lon, h, w, v in rows
    ]


def check_start_home(
    extensibility: dict | None, drone_id: str, home: Sequence[float] | None
) -> None:
    """A terrain-following mission's heights were placed above the ground at its plan
    home: a drone taking off from ground higher or lower than that by more than the
    tolerance would fly every point that much off its height above the terrain, so it is
    refused (409 terrain_clearance), as is a drone whose home has no terrain."""
    kept = (extensibility or {}).get(FIELD)
    if not kept:
        return
    planned = terrain.elevation(*kept["home"][:2])
    ground = terrain.elevation(float(home[0]), float(home[1])) if home is not None else None
    if planned is None or ground is None:
        raise MissionError("drone", f"{drone_id}'s home has no imported terrain: a terrain-following mission cannot be placed from it", 409, "terrain_clearance")  # fmt: skip
    offset = ground - planned
    if abs(offset) > kept["tolerance_m"]:
        raise MissionError(
            "drone",
            f"{drone_id} takes off from ground {offset:+.1f} m from the ground at the plan's "
            f"home, more than the mission's terrain-following tolerance of "
            f"{kept['tolerance_m']:g} m: every point would be that far off its height above "
            "the terrain. Plan the mission from this drone's home.",
            409,
            "terrain_clearance",
        )

"""The airspace a flight needs: its legs as corridors in space and time (no Django).

A flight is walked step by step, the way the drone's Navigation Processor flies it
(onboard/envelope.py `resolve`): a takeoff climbs in place, a `navigate` flies a straight
leg at the current height (plus its `altitude_delta`), `changeN`/`changeE` move
sideways, `altitude` climbs or descends in place, `land` descends to the ground, a
`sleep` hovers. Each leg becomes a corridor: the segment between its two ends with a
horizontal radius, an altitude band from its lowest to its highest height widened by the
vertical tolerance, and a time window.

Times: the flight's nominal clock runs at the leg's speed (a `navigate`'s own `speed`,
else the drone's cruise speed) and the climb rate. A drone may be faster (an autopilot
flying its own cruise speed) or slower (wind, acceleration, waypoints' tolerance
checks): a leg's window opens `buffer` seconds before its nominal start shrunk by `early`
(0.5: twice as fast) and closes `buffer` seconds after its nominal end stretched by
`slack` (0.5: half as slow again). Heights are metres above
the drone's home, as the envelope measures them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

EARTH_RADIUS = 6_378_137.0  # WGS-84 equatorial radius, as onboard/envelope.py uses
# Below this height a drone is on the ground: it takes no airspace.
GROUND_M = 0.5


@dataclass(frozen=True)
class Pace:
    """How fast a drone is assumed to fly, and how its legs' windows are widened."""

    speed_m_s: float = 5.0
    climb_m_s: float = 2.0
    slack: float = 0.5
    early: float = 0.5
    buffer_s: float = 30.0
    hold_s: float = 300.0  # how long the drone is assumed to hover after its last step
    radius_m: float = 2.0
    vertical_m: float = 2.0


@dataclass(frozen=True)
class Leg:
    """One corridor: from (lat0, lon0) to (lat1, lon1), heights low..high above home,
    reserved from t0 to t1 (seconds since the epoch)."""

    lat0: float
    lon0: float
    lat1: float
    lon1: float
    low: float
    high: float
    t0: float
    t1: float

    def to_list(self) -> list[float]:
        return [self.lat0, self.lon0, self.lat1, self.lon1, self.low, self.high, self.t0, self.t1]

    @classmethod
    def from_list(cls, values: Sequence[float]) -> Leg:
        return cls(*(float(v) for v in values[:8]))


@dataclass
class _Where:
    lat: float
    lon: float
    height: float
    seconds: float  # nominal time since the flight began


def offset(lat: float, lon: float, north: float, east: float) -> tuple[float, float]:
    """The point `north`, `east` metres from (lat, lon), on the local flat earth."""
    dlat = math.degrees(north / EARTH_RADIUS)
    dlon = math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat))))
    return lat + dlat, lon + dlon


def ground_distance(lat0: float, lon0: float, lat1: float, lon1: float) -> float:
    """Metres between two points on the local flat earth (as onboard/envelope.py)."""
    north = math.radians(lat1 - lat0) * EARTH_RADIUS
    east = math.radians(lon1 - lon0) * EARTH_RADIUS * math.cos(math.radians((lat0 + lat1) / 2))
    return math.hypot(north, east)


def _target(step: Mapping, here: _Where) -> tuple[float, float, float, float | None] | None:
    """Where a step sends the drone (lat, lon, height, its leg's own speed), or None for
    a step that does not move it."""
    command, params = step.get("command"), step.get("params") or {}
    if command == "takeoff":
        return here.lat, here.lon, float(params.get("altitude", 10.0)), None
    if command == "land":
        return here.lat, here.lon, 0.0, None
    if command == "altitude":
        return here.lat, here.lon, here.height + float(params["value"]), None
    if command in ("changeN", "changeE"):
        north = float(params["value"]) if command == "changeN" else 0.0
        east = float(params["value"]) if command == "changeE" else 0.0
        return (*offset(here.lat, here.lon, north, east), here.height, None)
    if command == "navigate":
        height = here.height + float(params.get("altitude_delta") or 0.0)
        speed = params.get("speed")
        return float(params["lat"]), float(params["lon"]), height, speed and float(speed)
    return None


def _leg(start: _Where, end: _Where, pace: Pace, began: float) -> Leg:
    t0 = began + start.seconds * pace.early - pace.buffer_s
    t1 = began + end.seconds * (1.0 + pace.slack) + pace.buffer_s
    low = max(0.0, min(start.height, end.height) - pace.vertical_m)
    high = max(start.height, end.height) + pace.vertical_m
    return Leg(start.lat, start.lon, end.lat, end.lon, low, high, t0, t1)


def _moves(steps: Sequence[Mapping], start: _Where, pace: Pace) -> Iterator[tuple[_Where, _Where]]:
    """(from, to) of each step that moves the drone or makes it hover, in flying order."""
    here = start
    for step in steps:
        if step.get("command") == "sleep":
            value = float((step.get("params") or {}).get("value", 0.0))
            end = _Where(here.lat, here.lon, here.height, here.seconds + value)
        else:
            target = _target(step, here)
            if target is None:
                continue
            lat, lon, height, speed = target
            across = ground_distance(here.lat, here.lon, lat, lon)
            seconds = (
                across / (speed or pace.speed_m_s) + abs(height - here.height) / pace.climb_m_s
            )
            end = _Where(lat, lon, height, here.seconds + seconds)
        yield here, end
        here = end


def flight_legs(
    steps: Sequence[Mapping],
    position: tuple[float, float, float],
    began: float,
    pace: Pace,
) -> tuple[list[Leg], float]:
    """The corridors of a flight from `position` (lat, lon, height above home) starting
    at `began`, and the latest time by which the drone should be airborne (its first
    corridor's nominal start, widened like a window's end; `began` when it flies already).

    Legs on the ground take no airspace; after its last step a drone still in the air
    hovers where it is for `pace.hold_s`.
    """
    start = _Where(position[0], position[1], max(0.0, position[2]), 0.0)
    legs: list[Leg] = []
    airborne_by: float | None = began if start.height >= GROUND_M else None
    last = start
    for a, b in _moves(steps, start, pace):
        last = b
        if max(a.height, b.height) < GROUND_M:
            continue
        if airborne_by is None:
            airborne_by = began + a.seconds * (1.0 + pace.slack) + pace.buffer_s
        legs.append(_leg(a, b, pace, began))
    if last.height >= GROUND_M:
        hover = _Where(last.lat, last.lon, last.height, last.seconds + pace.hold_s)
        legs.append(_leg(last, hover, pace, began))
    return legs, began if airborne_by is None else airborne_by


def hold_legs(position: tuple[float, float, float], began: float, pace: Pace) -> list[Leg]:
    """A drone in the air with no plan known: the column under it, from now for
    `pace.hold_s` (it hovers, or comes down where it is)."""
    lat, lon, height = position
    if height < GROUND_M:
        return []
    return [Leg(lat, lon, lat, lon, 0.0, height + pace.vertical_m, began, began + pace.hold_s)]


def with_takeoff_altitude(steps: Sequence[Mapping], altitude: float) -> list[dict]:
    """The steps with every takeoff climbing to `altitude` (a layer)."""
    out = []
    for step in steps:
        step = {**step, "params": dict(step.get("params") or {})}
        if step.get("command") == "takeoff":
            step["params"]["altitude"] = altitude
        out.append(step)
    return out


def takeoff_altitude(steps: Sequence[Mapping]) -> float | None:
    """The height the first takeoff climbs to, or None when the steps take off nowhere."""
    for step in steps:
        if step.get("command") == "takeoff":
            return float((step.get("params") or {}).get("altitude", 10.0))
    return None

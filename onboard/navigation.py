"""Navigation Processor: coordinates and commands → navigation targets for the flight controller.

dRonin only takes NED targets, so geographic requests are converted with the dRonin GCS's
formula ([Paula 2018], figure 4.13; docs/uavtalk.md "LLA → NED"): a sphere
of radius 6 378 137 m plus the home altitude, linearised about home.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

from .fc.base import FlightController, VehicleState

EARTH_RADIUS = 6_378_137.0  # metres, [Paula 2018] figure 4.13

# (lat, lon, alt MSL) of home, as the flight controller's HomeLocation holds it.
Home = tuple[float, float, float]
NED = tuple[float, float, float]


class NavigationError(Exception):
    """A navigation request that cannot be turned into a target (no home, no position)."""


def lla_to_ned(lat: float, lon: float, alt_msl: float, home: Home) -> NED:
    """WGS84 point (altitude above mean sea level) → North-East-Down metres from home."""
    home_lat, home_lon, home_alt = home
    radius = home_alt + EARTH_RADIUS
    north = radius * math.radians(lat - home_lat)
    east = math.cos(math.radians(home_lat)) * radius * math.radians(lon - home_lon)
    down = home_alt - alt_msl
    return north, east, down


def ned_to_lla(north: float, east: float, down: float, home: Home) -> tuple[float, float, float]:
    """The exact inverse of `lla_to_ned` (dRonin's own inverse has a precedence slip)."""
    home_lat, home_lon, home_alt = home
    radius = home_alt + EARTH_RADIUS
    lat = home_lat + math.degrees(north / radius)
    lon = home_lon + math.degrees(east / (radius * math.cos(math.radians(home_lat))))
    return lat, lon, home_alt - down


def euler_to_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """(w, x, y, z) from roll, pitch, yaw in degrees (aerospace Z-Y-X order)."""
    cr, sr = math.cos(math.radians(roll) / 2), math.sin(math.radians(roll) / 2)
    cp, sp = math.cos(math.radians(pitch) / 2), math.sin(math.radians(pitch) / 2)
    cy, sy = math.cos(math.radians(yaw) / 2), math.sin(math.radians(yaw) / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


@dataclass(frozen=True)
class Target:
    """A navigation target: what to do and where (NED metres from home)."""

    kind: str  # "takeoff", "land" or "goto"
    ned: NED


def current_ned(state: VehicleState) -> NED | None:
    """The vehicle's NED position: PositionActual when known, else from GPS and home."""
    if state.ned is not None:
        return state.ned
    if state.lat is not None and state.lon is not None and state.home is not None:
        alt = state.alt or 0.0
        return lla_to_ned(state.lat, state.lon, state.home[2] + alt, state.home)
    return None


def inside_cylinder(
    actual: NED, goal: NED, *, horizontal_tolerance: float, vertical_tolerance: float
) -> bool:
    """Inside the tolerance cylinder centred on the goal ([Paula 2018], algorithm 1)."""
    vertical_error = goal[2] - actual[2]
    horizontal_error = math.hypot(goal[0] - actual[0], goal[1] - actual[1])
    return abs(vertical_error) < vertical_tolerance and horizontal_error < horizontal_tolerance


class NavigationProcessor:
    """Turns navigation commands into targets relative to the last requested target.

    Relative commands (changeN/changeE/altitude) add to the last target, not to where the
    drone happens to be, so a chain of steps draws the planned shape even when the drone
    has not finished the previous leg.
    """

    def __init__(self, fc: FlightController) -> None:
        self.fc = fc
        self._lock = threading.Lock()
        self._target: Target | None = None

    @property
    def last_target(self) -> Target | None:
        with self._lock:
            return self._target

    def reset(self) -> None:
        with self._lock:
            self._target = None

    def plan(self, command: str, params: dict, state: VehicleState) -> Target:
        """The target a navigation command asks for, given the vehicle's state."""
        with self._lock:
            last = self._target
        base = last.ned if last is not None else current_ned(state)
        here = current_ned(state)
        if command == "takeoff":
            start = here or (0.0, 0.0, 0.0)
            return Target("takeoff", (start[0], start[1], -params["altitude"]))
        if command == "land":
            origin = here or base
            if origin is None:
                raise NavigationError("The drone's position is not known yet.")
            return Target("land", (origin[0], origin[1], 0.0))
        if base is None:
            raise NavigationError("The drone's position is not known yet (no GPS fix).")
        north, east, down = base
        if command == "changeN":
            return Target("goto", (north + params["value"], east, down))
        if command == "changeE":
            return Target("goto", (north, east + params["value"], down))
        if command == "altitude":
            return Target("goto", (north, east, down - params["value"]))
        if command == "navigate":
            if state.home is None:
                raise NavigationError("The flight controller has no home location yet.")
            target_n, target_e, _ = lla_to_ned(params["lat"], params["lon"], 0.0, state.home)
            return Target("goto", (target_n, target_e, down - params.get("altitude_delta", 0.0)))
        raise NavigationError(f"{command} is not a navigation command.")

    def hold_at(self, ned: NED) -> Target:
        """Fly to and hold an explicit NED point (fail-safe hold / return home)."""
        self.fc.goto_ned(*ned)
        target = Target("goto", ned)
        with self._lock:
            self._target = target
        return target

    def execute(self, command: str, params: dict) -> Target:
        """Plan the target, send it to the flight controller and remember it."""
        target = self.plan(command, params, self.fc.state)
        if target.kind == "takeoff":
            self.fc.takeoff(-target.ned[2])
        elif target.kind == "land":
            self.fc.land()
        else:
            self.fc.goto_ned(*target.ned)
        with self._lock:
            self._target = target
        return target

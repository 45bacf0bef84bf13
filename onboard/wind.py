"""Wind: the drone's own limit, the flight controller's estimate, and what the drone does.

The limit is the drone's gear: `MAX_WIND_M_S` in its specs.json (the horizontal wind
speed, m/s, it is rated to fly in), else DEFAULT_MAX_WIND_M_S. The wind is the flight
controller's own estimate, as the platform object `WindVelocityActual` (dRonin's name and
fields: North, East, Down in m/s, the air's velocity): a MAVLink driver makes it from
WIND_COV (PX4) [MAVLink WIND_COV] or WIND (ArduPilot) [MAVLink ardupilotmega]; a dRonin
board sends the object itself, if its firmware writes it (dRonin's own modules do not). A
flight controller that gives no estimate leaves the wind unknown, and nothing is refused
for it.

- A take-off (a control command or a mission step) while the wind is above the limit is
  refused with the figure.
- Airborne, a wind above the limit for longer than `hold_s` flight seconds makes the
  fail-safe return the drone home, as PX4's high-wind fail-safe does (COM_WIND_MAX with
  COM_WIND_MAX_ACT) [PX4 COM_WIND_MAX]; the heartbeat's `wind.action` says so until the
  drone is on the ground again. One estimate above the limit (a gust) is not enough.

The ground imports this module too (standard library and onboard.protocol only).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from . import protocol

# The specs.json key of the drone's limit.
SPEC_KEY = "MAX_WIND_M_S"
# The platform's own default when the gear states no limit: the top of Beaufort force 5
# ("fresh breeze", 8.0-10.7 m/s) rounded down [WMO No. 8], a wind small multirotors are
# commonly rated for. Set the gear's own figure from its maker.
DEFAULT_MAX_WIND_M_S = 10.0
# A limit above this is a typing error (hurricane force begins at 32.7 m/s [WMO No. 8]).
MAX_WIND_LIMIT_M_S = 40.0
# Flight seconds the wind must stay above the limit before the drone returns: longer than
# a gust, which is reported over 3 s [WMO No. 8], so one gust does not end a flight.
DEFAULT_HOLD_S = 10.0
# An estimate older than this (wall seconds) is no longer the wind: unknown again.
STALE_AFTER_S = 10.0
# The platform object the wind arrives as, whatever the flight controller speaks.
OBJECT = "WindVelocityActual"


class WindLimitError(ValueError):
    """A wind limit that is not a number from 0 to MAX_WIND_LIMIT_M_S; str() says so."""


def parse_limit(value: Any, name: str = SPEC_KEY) -> float:
    """A wind limit in m/s, or WindLimitError naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WindLimitError(f"{name} must be a number of m/s, got {value!r}")
    limit = float(value)
    if not math.isfinite(limit) or not 0.0 < limit <= MAX_WIND_LIMIT_M_S:
        raise WindLimitError(
            f"{name} must be above 0 and at most {MAX_WIND_LIMIT_M_S:g} m/s, got {value!r}"
        )
    return limit


def limit_from_specs(specs: Mapping[str, Any] | None) -> float:
    """The gear's limit (WindLimitError when it is malformed), else the default."""
    value = (specs or {}).get(SPEC_KEY)
    return DEFAULT_MAX_WIND_M_S if value is None else parse_limit(value)


@dataclass(frozen=True)
class Wind:
    """The air's velocity (m/s, North-East-Down) where the drone is, and who estimated it."""

    north: float
    east: float
    down: float
    source: str
    at: float = 0.0  # time.monotonic() when it arrived

    @property
    def speed(self) -> float:
        """Horizontal speed, m/s: what the limit is about."""
        return math.hypot(self.north, self.east)

    @property
    def from_deg(self) -> float:
        """Where the wind comes from, degrees clockwise from north (meteorological)."""
        return math.degrees(math.atan2(-self.east, -self.north)) % 360.0


def wind_from_object(fields: Mapping[str, Any], at: float = 0.0) -> Wind | None:
    """A WindVelocityActual object's fields → Wind; None when a component is not a number
    (WIND_COV's NaN: unknown)."""
    try:
        values = [float(fields[k]) for k in ("North", "East", "Down")]
    except (KeyError, TypeError, ValueError):
        return None
    if not all(math.isfinite(v) for v in values):
        return None
    return Wind(*values, source=str(fields.get("Source") or "flight controller"), at=at)


def refusal(speed: float, limit: float) -> str | None:
    """The sentence refusing a take-off in this wind, or None when it is within the limit."""
    if speed <= limit:
        return None
    return (
        f"Wind {speed:.1f} m/s is above this drone's limit of {limit:g} m/s "
        "(its flight controller's estimate): take-off refused."
    )


# (command, target kind, target NED, vehicle state, is a mission step, leg start)
Guard = Callable[[str, str, tuple, Any, bool, tuple | None], str | None]


def guards(*checks: Guard) -> Guard:
    """One guard asking each in turn: the first refusal wins."""

    def check(*args: Any) -> str | None:
        for guard in checks:
            found = guard(*args)
            if found is not None:
                return found
        return None

    return check


class WindWatch:
    """The drone's wind rule: the latest estimate, the take-off guard, the in-flight watch.

    `limit` reads the gear's limit (it may change as specs.json is re-read); `return_home`
    is the fail-safe's (onboard/failsafe.py). Waits are flight seconds: wall seconds ×
    `time_scale` in simulation, as the fail-safe's auto-disarm delay.
    """

    def __init__(
        self,
        limit: Callable[[], float],
        return_home: Callable[[str], str],
        *,
        hold_s: float = DEFAULT_HOLD_S,
        time_scale: float = 1.0,
        clock: Callable[[], float] | None = None,
    ) -> None:
        if hold_s < 0:
            raise ValueError("the wind hold time must not be negative")
        self.limit = limit
        self.return_home = return_home
        self.hold_s = hold_s
        self.time_scale = time_scale
        self.clock = clock or time.monotonic
        self._lock = threading.Lock()
        self._wind: Wind | None = None
        self._above_since: float | None = None
        # What the watch made the drone do ("return"), and since when (epoch seconds).
        self.action: str | None = None
        self.action_since: float | None = None

    def on_object(self, name: str, ts: float, fields: dict) -> None:
        """A flight-controller listener: keep the newest wind estimate."""
        if name != OBJECT:
            return
        wind = wind_from_object(fields, self.clock())
        if wind is not None:
            with self._lock:
                self._wind = wind

    def current(self) -> Wind | None:
        """The newest estimate, None when there is none or it is stale."""
        with self._lock:
            wind = self._wind
        if wind is None or self.clock() - wind.at > STALE_AFTER_S:
            return None
        return wind

    def guard(
        self,
        command: str,
        kind: str,
        ned: tuple,
        state: Any,
        in_mission: bool = False,
        start: tuple | None = None,
    ) -> str | None:
        """The controller's guard: a take-off from the ground above the limit is refused."""
        if kind != "takeoff" or state.airborne:
            return None
        wind = self.current()
        return None if wind is None else refusal(wind.speed, self.limit())

    def tick(self, state: Any) -> str | None:
        """Return the drone once the wind has stayed above the limit for `hold_s` while
        airborne; what the fail-safe did, or None."""
        if not state.armed:
            self.action = self.action_since = None
        wind = self.current()
        limit = self.limit()
        now = self.clock()
        if wind is None or wind.speed <= limit or not state.airborne:
            self._above_since = None
            return None
        if self._above_since is None:
            self._above_since = now
        held = (now - self._above_since) * self.time_scale
        if held < self.hold_s or self.action is not None:
            return None
        self.action, self.action_since = "return", time.time()
        return self.return_home(
            f"wind {wind.speed:.1f} m/s above the limit of {limit:g} m/s for {held:.0f} s"
        )

    def with_report(self, beat: protocol.Heartbeat) -> protocol.Heartbeat:
        """The heartbeat with its `wind` (unchanged when no estimate is known)."""
        report = self.report()
        return beat if report is None else replace(beat, wind=protocol.WindReport(**report))

    def report(self) -> dict | None:
        """The heartbeat's `wind` (docs/protocol.md), None when no estimate is known."""
        wind = self.current()
        if wind is None:
            return None
        report = {
            "north": round(wind.north, 2),
            "east": round(wind.east, 2),
            "down": round(wind.down, 2),
            "speed": round(wind.speed, 2),
            "limit": self.limit(),
            "source": wind.source,
        }
        if self.action is not None:
            report.update(action=self.action, since=self.action_since)
        return report

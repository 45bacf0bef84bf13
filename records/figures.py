"""A flight's figures from its telemetry samples, in one pass: plain Python, no database.

Samples arrive in time order as (epoch seconds, object name, fields). The objects read
are the platform's names for what every flight controller reports (the MAVLink driver
maps its messages onto them, onboard/fc/mavlink.py): `FlightStatus.Armed`,
`PositionActual` (North, East, Down in metres from home), `VelocityActual` (m/s, NED),
`GPSPosition` (Latitude, Longitude in 1e-7 degrees) and `FlightBatteryState` (Voltage V,
Current A).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from batteries.health import SagEstimator

# Above this height over home the drone is airborne: take-off is the first sample above
# it, landing the last.
AIRBORNE_HEIGHT_M = 0.5
# Distance flown counts a move only once the drone is this far from the last point
# counted, so position noise while hovering adds nothing.
MIN_STEP_M = 0.2
# The track kept in the record is thinned to one point per this many metres or seconds.
TRACK_STEP_M = 5.0
TRACK_STEP_S = 5.0
MAX_TRACK_POINTS = 2000
# Samples apart by more than this are not joined when integrating power (a gap in the
# telemetry is not assumed flown at the last power).
MAX_POWER_GAP_S = 5.0

OBJECTS = ("FlightStatus", "PositionActual", "VelocityActual", "GPSPosition", "FlightBatteryState")


@dataclass
class Figures:
    """What one flight's samples say; None where they say nothing."""

    started_at: float | None = None
    ended_at: float | None = None
    takeoff_at: float | None = None
    landing_at: float | None = None
    takeoff_position: dict | None = None
    landing_position: dict | None = None
    distance_m: float | None = None
    max_height_m: float | None = None
    max_speed_ms: float | None = None
    max_distance_m: float | None = None
    voltage_start: float | None = None
    voltage_end: float | None = None
    energy_wh: float | None = None
    # The pack's internal resistance from voltage sag against current (batteries.health).
    resistance_ohm: float | None = None
    track: list[list[float]] = field(default_factory=list)
    samples: int = 0


def _number(fields: dict, name: str) -> float | None:
    value = fields.get(name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


class Accumulator:
    """Feed samples with `add`, in time order; `result()` gives the figures.

    `opened` and `closed` are the ground's times for arming and disarming (heartbeats).
    A `FlightStatus` sample reading Armed (the first) and Disarmed (the first after it)
    set the flight's bounds more exactly; samples outside the bounds are left out.
    """

    def __init__(self, opened: float, closed: float) -> None:
        self.out = Figures()
        self.opened = opened
        self.closed = closed
        self._armed_seen: float | None = None
        self._disarmed_seen: float | None = None
        self._pending: list[tuple[float, str, dict]] = []
        self._anchor: tuple[float, float] | None = None
        self._last_gps: dict | None = None
        self._last_power: tuple[float, float] | None = None
        self._last_track: tuple[float, float, float] | None = None
        self._sag = SagEstimator()

    def add(self, ts: float, name: str, fields: dict) -> None:
        if name == "FlightStatus":
            self._status(ts, fields)
            return
        if self._disarmed_seen is not None and ts > self._disarmed_seen:
            return
        if self._armed_seen is None and ts > self.closed:
            return  # no FlightStatus samples: the ground's bounds hold
        if self._armed_seen is None and ts < self.opened:
            # Before the first Armed sample: kept until it is known whether one comes.
            self._pending.append((ts, name, fields))
            return
        self._take(ts, name, fields)

    def _status(self, ts: float, fields: dict) -> None:
        armed = fields.get("Armed") == "Armed"
        if armed and self._armed_seen is None and self._disarmed_seen is None:
            self._armed_seen = ts
            self._pending = [p for p in self._pending if p[0] >= ts]
            for pending in self._pending:
                self._take(*pending)
            self._pending = []
        elif not armed and self._armed_seen is not None and self._disarmed_seen is None:
            self._disarmed_seen = ts

    def _take(self, ts: float, name: str, fields: dict) -> None:
        self.out.samples += 1
        if name == "PositionActual":
            self._position(ts, fields)
        elif name == "VelocityActual":
            self._velocity(fields)
        elif name == "GPSPosition":
            self._gps(fields)
        elif name == "FlightBatteryState":
            self._battery(ts, fields)

    def _position(self, ts: float, fields: dict) -> None:
        north, east, down = (_number(fields, k) for k in ("North", "East", "Down"))
        if north is None or east is None or down is None:
            return
        out = self.out
        height = -down
        out.max_height_m = height if out.max_height_m is None else max(out.max_height_m, height)
        away = math.hypot(north, east)
        out.max_distance_m = away if out.max_distance_m is None else max(out.max_distance_m, away)
        if height > AIRBORNE_HEIGHT_M:
            if out.takeoff_at is None:
                out.takeoff_at = ts
                out.takeoff_position = self._last_gps
            out.landing_at = ts
        self._distance(north, east)
        self._keep_track(ts, north, east, height)

    def _distance(self, north: float, east: float) -> None:
        if self._anchor is None:
            self._anchor = (north, east)
            self.out.distance_m = 0.0
            return
        step = math.hypot(north - self._anchor[0], east - self._anchor[1])
        if step >= MIN_STEP_M:
            self.out.distance_m = (self.out.distance_m or 0.0) + step
            self._anchor = (north, east)

    def _keep_track(self, ts: float, north: float, east: float, height: float) -> None:
        last = self._last_track
        if last is not None:
            moved = math.hypot(north - last[1], east - last[2])
            if moved < TRACK_STEP_M and ts - last[0] < TRACK_STEP_S:
                return
        if len(self.out.track) >= MAX_TRACK_POINTS:
            return
        self._last_track = (ts, north, east)
        self.out.track.append([ts, round(north, 2), round(east, 2), round(height, 2)])

    def _velocity(self, fields: dict) -> None:
        north, east = _number(fields, "North"), _number(fields, "East")
        if north is None or east is None:
            return
        speed = math.hypot(north, east)
        out = self.out
        out.max_speed_ms = speed if out.max_speed_ms is None else max(out.max_speed_ms, speed)

    def _gps(self, fields: dict) -> None:
        lat, lon = _number(fields, "Latitude"), _number(fields, "Longitude")
        if lat is None or lon is None or (lat == 0 and lon == 0):
            return
        self._last_gps = {"lat": lat / 1e7, "lon": lon / 1e7}
        # Where the drone was last seen in the flight: it lands there and is disarmed.
        self.out.landing_position = self._last_gps

    def _battery(self, ts: float, fields: dict) -> None:
        voltage, current = _number(fields, "Voltage"), _number(fields, "Current")
        if voltage is None:
            return
        out = self.out
        if out.voltage_start is None:
            out.voltage_start = voltage
        out.voltage_end = voltage
        if current is None:
            return
        self._sag.add(ts, voltage, current)
        power = voltage * current
        last = self._last_power
        if last is not None and 0 < ts - last[0] <= MAX_POWER_GAP_S:
            # Trapezoidal integration of P = V·I; W·s → Wh.
            joules = (ts - last[0]) * (power + last[1]) / 2
            out.energy_wh = (out.energy_wh or 0.0) + joules / 3600.0
        self._last_power = (ts, power)

    def result(self) -> Figures:
        out = self.out
        out.started_at = self._armed_seen if self._armed_seen is not None else self.opened
        out.ended_at = self._disarmed_seen if self._disarmed_seen is not None else self.closed
        out.resistance_ohm = self._sag.result()
        if out.started_at is not None and out.track:
            out.track = [[round(p[0] - out.started_at, 1), *p[1:]] for p in out.track]
        return out

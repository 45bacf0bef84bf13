"""What a drone is doing, at a glance, from the fields its heartbeats carry.

Plain functions and one small per-process tracker: the fleet pages, the paged drone API and
the live updates all call `drone_state`, so a marker, a table row and a filter never
disagree about a drone.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any

# The states, most urgent first: when several hold, a drone shows the first one.
LOST_LINK = "lost_link"
LOW_BATTERY = "low_battery"
RETURNING = "returning"
AIRBORNE = "airborne"
ARMED = "armed"
ON_GROUND = "on_ground"
STATES = (LOST_LINK, LOW_BATTERY, RETURNING, AIRBORNE, ARMED, ON_GROUND)
LABELS = {
    LOST_LINK: "lost link",
    LOW_BATTERY: "low battery",
    RETURNING: "returning",
    AIRBORNE: "airborne",
    ARMED: "armed",
    ON_GROUND: "on ground",
}

# At or below this fraction of charge a drone is shown as low on battery.
LOW_BATTERY_FRACTION = 0.25
# Flight-controller mode names (MAVLink/ArduPilot, PX4, LibrePilot) that fly the drone home.
_RETURN_MODES = ("RTL", "RETURN", "RTH", "RETURNTOBASE", "SMART_RTL", "AUTO.RTL")
# Below this ground speed (m/s) a course from two positions is GPS noise: no heading.
MIN_SPEED_FOR_HEADING = 0.5
# Battery drain is measured over at least this span, since the reported charge is coarse.
MIN_DRAIN_SPAN_S = 10.0
DRAIN_WINDOW_S = 120.0
# A charge this much above the last reading is another battery, not a noisy reading.
BATTERY_SWAP_RISE = 0.02
EARTH_RADIUS_M = 6371008.8


def is_returning_mode(flight_mode: str | None) -> bool:
    mode = (flight_mode or "").upper().replace(" ", "")
    return any(mode == name or mode.endswith("." + name) for name in _RETURN_MODES)


def drone_state(
    *,
    online: bool,
    armed: bool,
    airborne: bool,
    flight_mode: str | None = None,
    battery_remaining: float | None = None,
    low_battery: float = LOW_BATTERY_FRACTION,
) -> str:
    """One of STATES: lost link (no heartbeat), low battery, returning home (the flight
    controller's return mode while airborne), airborne, armed on the ground, on the ground."""
    if not online:
        return LOST_LINK
    if battery_remaining is not None and battery_remaining <= low_battery:
        return LOW_BATTERY
    if airborne and is_returning_mode(flight_mode):
        return RETURNING
    if airborne:
        return AIRBORNE
    if armed:
        return ARMED
    return ON_GROUND


def state_of(drone: dict) -> str:
    """`drone_state` of a drone in the API's shape (`battery` may be None)."""
    battery = drone.get("battery") or {}
    return drone_state(
        online=bool(drone.get("online")),
        armed=bool(drone.get("armed")),
        airborne=bool(drone.get("airborne")),
        flight_mode=drone.get("flight_mode"),
        battery_remaining=battery.get("remaining"),
    )


def ground_track(
    a: tuple[float, float], b: tuple[float, float], seconds: float
) -> tuple[float, float | None] | None:
    """Ground speed (m/s) and course (degrees from north, clockwise) from lat/lon `a` to
    `b` in `seconds`; the course is None when slower than MIN_SPEED_FOR_HEADING."""
    if seconds <= 0:
        return None
    lat1, lon1, lat2, lon2 = (math.radians(v) for v in (*a, *b))
    d_lat, d_lon = lat2 - lat1, lon2 - lon1
    h = math.sin(d_lat / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin(d_lon / 2) ** 2
    distance = 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(h)))
    speed = distance / seconds
    if speed < MIN_SPEED_FOR_HEADING:
        return speed, None
    y = math.sin(d_lon) * math.cos(lat2)
    x = math.cos(lat1) * math.sin(lat2) - math.sin(lat1) * math.cos(lat2) * math.cos(d_lon)
    return speed, math.degrees(math.atan2(y, x)) % 360.0


def battery_time_left(remaining: float | None, drain_per_s: float | None) -> float | None:
    """Seconds until empty at the measured drain; None while the drain is unknown or nil."""
    if remaining is None or drain_per_s is None or drain_per_s <= 0:
        return None
    return max(0.0, remaining) / drain_per_s


def drain_rate(samples: list[tuple[float, float]]) -> float | None:
    """Charge fraction per second between the oldest and newest (time, remaining) sample,
    once they span MIN_DRAIN_SPAN_S; None before, or while charging."""
    if len(samples) < 2:
        return None
    (t0, r0), (t1, r1) = samples[0], samples[-1]
    if t1 - t0 < MIN_DRAIN_SPAN_S or r1 > r0:
        return None
    return (r0 - r1) / (t1 - t0)


@dataclass
class _Track:
    t: float
    lat: float
    lon: float
    battery: deque


class Motion:
    """Per drone: speed, course and battery time left from its successive heartbeats.

    Held by the process that receives the heartbeats; a drone whose heartbeats alternate
    between processes gets the figures of a longer baseline, still right."""

    def __init__(self) -> None:
        self._tracks: dict[str, _Track] = {}
        self._lock = threading.Lock()

    def update(self, drone_id: str, t: float, position: dict | None, remaining: Any) -> dict:
        """The derived fields for a heartbeat at `t` (seconds): ground_speed, heading,
        battery_time_left_s, battery_drain_per_s (each None while unknown)."""
        with self._lock:
            track = self._tracks.get(drone_id)
            out: dict[str, float | None] = {"ground_speed": None, "heading": None}
            if position is None:
                return {**out, "battery_time_left_s": None, "battery_drain_per_s": None}
            if track is None:
                track = self._tracks[drone_id] = _Track(t, 0.0, 0.0, deque())
            elif t > track.t:
                moved = ground_track(
                    (track.lat, track.lon), (position["lat"], position["lon"]), t - track.t
                )
                if moved is not None:
                    out["ground_speed"], out["heading"] = round(moved[0], 2), _round(moved[1])
            track.t, track.lat, track.lon = t, position["lat"], position["lon"]
            if remaining is not None:
                if track.battery and remaining > track.battery[-1][1] + BATTERY_SWAP_RISE:
                    track.battery.clear()  # a fresh or charged battery: measure anew
                track.battery.append((t, float(remaining)))
                while track.battery and t - track.battery[0][0] > DRAIN_WINDOW_S:
                    track.battery.popleft()
            drain = drain_rate(list(track.battery))
            left = battery_time_left(remaining, drain)
            return {
                **out,
                "battery_time_left_s": _round(left),
                "battery_drain_per_s": None if drain is None else round(drain, 7),
            }


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 1)


def describe(drone: dict) -> dict:
    """`drone` (API shape) with its state, for pages that show it."""
    return {**drone, "state": state_of(drone)}

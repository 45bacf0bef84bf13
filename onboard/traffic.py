"""Traffic: the agent's last-resort separation check (docs/protocol.md "Traffic",
docs/airspace.md "Live separation").

The ground relays, with each live-separation pass, the other airborne drones of this
drone's airspace on `<id>/traffic/in`: position (WGS 84 and height above home: heights of
one airspace are compared as heights above each drone's own home, the rule the ground's
own check uses), velocity (m/s east, north, up, per second of the ground's clock), the
separation minima of the pair and the ground's time stamp, plus this drone's reservation
band. The agent keeps the newest of each drone, forgets one older than `STALE_S`, and
flies them on in straight lines against its own position and velocity from the flight
controller over `HORIZON_S` — shorter than the ground's ten seconds, so the ground, which
can pick which drone of a pair holds, acts first and the agent only when the ground has
not. On a predicted loss of separation the drone holds where it is (as the operator's
Hold: a running mission paused, else the fail-safe's hold), raises one CRITICAL alarm per
encounter and resumes nothing by itself: the operator decides. A malformed message is
dropped and counted by reason; it changes nothing.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from . import protocol
from .fc.base import VehicleState

# Seconds ahead the agent flies both drones on: shorter than the ground's 10 s
# (AIRSPACE_LIVE_HORIZON_S) so that the ground, which holds only one drone of a pair,
# acts first; in flight seconds (divided by the simulator's time scale).
HORIZON_S = 6.0
STEP_S = 0.25
# A relayed position older than this (seconds on the ground's clock) is dropped: flown on
# any further, a straight line says little about a drone that can turn.
STALE_S = 3.0
# Entries one message may carry; the ground sends at most AIRSPACE_TRAFFIC_MAX (8).
MAX_ENTRIES = 32
# Bounds of a believable relayed value: speeds of small drones, heights above home.
MAX_SPEED_M_S = 100.0
MAX_HEIGHT_M = 10_000.0
MAX_MINIMUM_M = 10_000.0
EARTH_RADIUS = 6_371_000.0


class TrafficError(ValueError):
    """A traffic message that breaks docs/protocol.md; `reason` is what it is counted as."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class Other:
    """Another airborne drone as the ground relays it."""

    drone_id: str
    lat: float
    lon: float
    alt: float
    ve: float
    vn: float
    vu: float
    horizontal_min_m: float
    vertical_min_m: float


@dataclass(frozen=True)
class TrafficUpdate:
    ts: float
    band: tuple[float, float] | None
    others: tuple[Other, ...]


@dataclass(frozen=True)
class Encounter:
    """This drone and `other` predicted within the minima `in_s` seconds from now."""

    other: str
    in_s: float
    horizontal_m: float
    vertical_m: float


def _number(value: Any, reason: str, field: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TrafficError(reason, f"{field} must be a number")
    if not math.isfinite(value) or not lo <= value <= hi:
        raise TrafficError(reason, f"{field} must be within {lo:g}..{hi:g}")
    return float(value)


def _band(value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 2:
        raise TrafficError("band", "band must be [low, high] metres above home or null")
    low = _number(value[0], "band", "band[0]", -MAX_HEIGHT_M, MAX_HEIGHT_M)
    high = _number(value[1], "band", "band[1]", -MAX_HEIGHT_M, MAX_HEIGHT_M)
    if low > high:
        raise TrafficError("band", "band's low is above its high")
    return low, high


def _other(value: Any, k: int) -> Other:
    at = f"traffic[{k}]"
    if not isinstance(value, dict):
        raise TrafficError("shape", f"{at} must be an object")
    if not protocol.is_drone_id(value.get("drone_id")):
        raise TrafficError("drone_id", f"{at}.drone_id is not a drone id")
    lat = _number(value.get("lat"), "position", f"{at}.lat", -90, 90)
    lon = _number(value.get("lon"), "position", f"{at}.lon", -180, 180)
    alt = _number(value.get("alt"), "position", f"{at}.alt", -MAX_HEIGHT_M, MAX_HEIGHT_M)
    speeds = [
        _number(value.get(k), "velocity", f"{at}.{k}", -MAX_SPEED_M_S, MAX_SPEED_M_S)
        for k in ("ve", "vn", "vu")
    ]
    horizontal = _number(value.get("horizontal_min_m"), "minima", f"{at}.horizontal_min_m", 0, MAX_MINIMUM_M)  # fmt: skip
    vertical = _number(value.get("vertical_min_m"), "minima", f"{at}.vertical_min_m", 0, MAX_MINIMUM_M)  # fmt: skip
    return Other(value["drone_id"], lat, lon, alt, *speeds, horizontal, vertical)


def parse_traffic(obj: Any) -> TrafficUpdate:
    """A `<id>/traffic/in` message, or TrafficError naming what is wrong."""
    if not isinstance(obj, dict):
        raise TrafficError("shape", "a traffic message must be an object")
    ts = _number(obj.get("ts"), "ts", "ts", 0, 1e11)
    entries = obj.get("traffic")
    if not isinstance(entries, list):
        raise TrafficError("shape", "traffic must be a list")
    if len(entries) > MAX_ENTRIES:
        raise TrafficError("too_many", f"at most {MAX_ENTRIES} traffic entries")
    others = tuple(_other(entry, k) for k, entry in enumerate(entries))
    return TrafficUpdate(ts, _band(obj.get("band")), others)


def traffic_message(ts: float, band: tuple[float, float] | None, others: Sequence[Other]) -> dict:
    """The ground's side: the message `parse_traffic` reads."""
    return {
        "ts": ts,
        "band": None if band is None else [band[0], band[1]],
        "traffic": [
            {
                "drone_id": o.drone_id,
                "lat": o.lat,
                "lon": o.lon,
                "alt": o.alt,
                "ve": o.ve,
                "vn": o.vn,
                "vu": o.vu,
                "horizontal_min_m": o.horizontal_min_m,
                "vertical_min_m": o.vertical_min_m,
            }
            for o in others
        ],
    }


def first_loss(
    own: tuple[float, float, float, float, float, float],
    other: tuple[float, float, float, float, float, float],
    minima: tuple[float, float],
    horizon_s: float,
    step_s: float = STEP_S,
) -> tuple[float, float, float] | None:
    """Two drones (east, north, up metres; their velocities) flown on in straight lines:
    the first sampled moment within `horizon_s` at which they are closer than the
    horizontal minimum while closer than the vertical one (docs/airspace.md), as
    (seconds, horizontal, vertical metres), or None."""
    rel = [other[i] - own[i] for i in range(6)]
    steps = int(horizon_s / step_s + 0.5)
    for n in range(steps + 1):
        t = n * step_s
        horizontal = math.hypot(rel[0] + rel[3] * t, rel[1] + rel[4] * t)
        vertical = abs(rel[2] + rel[5] * t)
        if horizontal < minima[0] and vertical < minima[1]:
            return t, horizontal, vertical
    return None


class TrafficWatch:
    """The newest relayed position of each other drone and the check against them."""

    def __init__(
        self,
        drone_id: str,
        state: Callable[[], VehicleState],
        *,
        time_scale: float = 1.0,
        horizon_s: float = HORIZON_S,
        stale_s: float = STALE_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.drone_id = drone_id
        self.state = state
        self.time_scale = time_scale
        self.horizon_s = horizon_s
        self.stale_s = stale_s
        self.clock = clock
        self._others: dict[str, tuple[Other, float]] = {}  # id → (other, clock at its ts)
        self._encounters: set[str] = set()
        self._lock = threading.Lock()

    def receive(self, update: TrafficUpdate, age_s: float) -> bool:
        """Keep the update's drones; `age_s` is how old it was on arrival (ground clock).
        False (nothing kept) when it arrived stale."""
        now = self.clock()
        if age_s > self.stale_s:
            return False
        with self._lock:
            for other in update.others:
                if other.drone_id != self.drone_id:
                    self._others[other.drone_id] = (other, now - max(0.0, age_s))
        return True

    def current(self) -> list[tuple[Other, float]]:
        """The drones not stale, each with its age in seconds; stale ones are forgotten."""
        now = self.clock()
        with self._lock:
            for drone_id in [k for k, (_, at) in self._others.items() if now - at > self.stale_s]:
                del self._others[drone_id]
            return [(other, now - at) for other, at in self._others.values()]

    def check(self) -> list[Encounter]:
        """The encounters that are new since the last check (one per other drone until a
        check predicts it clear again); none while this drone is not airborne."""
        state = self.state()
        own = _own_track(state, self.time_scale)
        if own is None or not state.airborne:
            self._encounters.clear()
            return []
        horizon = self.horizon_s / self.time_scale
        found: dict[str, Encounter] = {}
        for other, age in self.current():
            east, north = _local(other.lat, other.lon, state.lat, state.lon)  # type: ignore[arg-type]
            # Flown on from its time stamp to now.
            track = (
                east + other.ve * age, north + other.vn * age, other.alt + other.vu * age,
                other.ve, other.vn, other.vu,
            )  # fmt: skip
            loss = first_loss(own, track, (other.horizontal_min_m, other.vertical_min_m), horizon)
            if loss is not None:
                found[other.drone_id] = Encounter(other.drone_id, *loss)
        new = [e for k, e in found.items() if k not in self._encounters]
        self._encounters = set(found)
        return new


def _own_track(
    state: VehicleState, time_scale: float
) -> tuple[float, float, float, float, float, float] | None:
    """This drone at the origin, its height above home and its velocity per second of the
    ground's clock (the flight controller's is per flight second)."""
    if state.lat is None or state.lon is None or state.alt is None:
        return None
    vn, ve, vd = state.velocity_ned or (0.0, 0.0, 0.0)
    return 0.0, 0.0, state.alt, ve * time_scale, vn * time_scale, -vd * time_scale


def _local(lat: float, lon: float, lat0: float, lon0: float) -> tuple[float, float]:
    """East and north metres of (lat, lon) from (lat0, lon0), equirectangular: exact to
    well under a metre over the few hundred metres traffic is relayed within."""
    north = math.radians(lat - lat0) * EARTH_RADIUS
    east = math.radians(lon - lon0) * EARTH_RADIUS * math.cos(math.radians(lat0))
    return east, north


def inside_band(height: float, band: tuple[float, float] | None) -> float:
    """`height` moved into `band` (unchanged without one)."""
    if band is None:
        return height
    return min(max(height, band[0]), band[1])

"""The interface every flight-controller driver implements (UAVTalk, MAVLink, ...).

The agent (controller, navigation, mission worker, fail-safe, logger) only talks to
this interface, so a mixed fleet behaves the same whatever protocol a drone speaks.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Protocol


class FlightControllerError(Exception):
    """A command the flight controller refused, or a link that is not there."""


class NotConnected(FlightControllerError):
    pass


class CommandTimeout(FlightControllerError):
    pass


@dataclass(frozen=True)
class VehicleState:
    """What the agent knows of the vehicle; every field comes from the flight controller."""

    protocol: str = "uavtalk"
    connected: bool = False
    armed: bool = False
    arming: bool = False
    flight_mode: str = "UNKNOWN"
    # WGS84 position; alt is metres above home. None until the first GPS fix.
    lat: float | None = None
    lon: float | None = None
    alt: float | None = None
    # North-East-Down metres from home, as the flight controller reports it.
    ned: tuple[float, float, float] | None = None
    velocity_ned: tuple[float, float, float] | None = None
    roll: float | None = None
    pitch: float | None = None
    yaw: float | None = None
    # (qx, qy, qz, qw)
    quaternion: tuple[float, float, float, float] | None = None
    battery_voltage: float | None = None
    battery_remaining: float | None = None  # 0..1
    # (lat, lon, alt MSL) of the home point, None until the FC has set it.
    home: tuple[float, float, float] | None = None
    gps_fix: bool = False
    satellites: int = 0
    updated_at: float = 0.0  # time.monotonic() of the newest object
    # What to change on the flight controller before the agent can fly it (sentences,
    # e.g. "set ManualControlSettings.Arming to …"); empty when nothing is known wrong.
    setup: tuple[str, ...] = ()
    # The battery's serial number where the flight controller reports one (MAVLink
    # SMART_BATTERY_INFO or BATTERY_INFO); None otherwise.
    battery_serial: str | None = None

    @property
    def airborne(self) -> bool:
        """Armed and more than half a metre above home."""
        return bool(self.armed and self.alt is not None and self.alt > 0.5)

    def with_changes(self, **changes: Any) -> VehicleState:
        return replace(self, **changes)


# (object name, board or receive time in epoch seconds, fields as plain JSON values)
ObjectListener = Callable[[str, float, dict], None]


class FlightController(Protocol):
    """A driver for one flight controller on one link."""

    protocol: str

    def start(self) -> None:
        """Open the link and keep it open (handshake, keep-alive, reconnect) in the background."""

    def stop(self) -> None:
        """Close the link and stop background threads."""

    @property
    def state(self) -> VehicleState: ...

    def add_listener(self, listener: ObjectListener) -> None:
        """Call listener for every telemetry object received (from a driver thread)."""

    def wait_connected(self, timeout: float) -> bool: ...

    def arm(self, timeout: float = 10.0) -> None:
        """Arm and return once the flight controller reports Armed; raise on refusal/timeout."""

    def disarm(self, timeout: float = 10.0) -> None: ...

    def goto_ned(self, north: float, east: float, down: float) -> None:
        """Fly to and hold a North-East-Down position (metres from home)."""

    def takeoff(self, altitude: float) -> None:
        """Climb vertically above the current horizontal position to altitude above home."""

    def land(self) -> None:
        """Descend and land at the current horizontal position."""

    def request_object(self, name: str, timeout: float = 2.0) -> dict:
        """Ask for an object's current fields and return them."""

    def write_object(self, name: str, fields: dict, timeout: float = 2.0) -> None:
        """Write an object (fields not given keep their last known value)."""

    def rebuild_link(self) -> None:
        """Drop and re-establish the link (the `rebuildtelemetry` command)."""

    def reset(self) -> None:
        """Reboot the flight controller (the `resetfc` command)."""


@dataclass
class StateHolder:
    """Thread-safe holder for a driver's VehicleState, replaced atomically."""

    _state: VehicleState = field(default_factory=VehicleState)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def get(self) -> VehicleState:
        with self._lock:
            return self._state

    def update(self, **changes: Any) -> VehicleState:
        with self._lock:
            self._state = replace(self._state, **changes)
            return self._state

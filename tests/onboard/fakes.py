"""A small in-test flight controller for unit tests of the mission worker only.

It implements onboard.fc.base.FlightController with no link at all: targets are recorded
and the position moves only when the test says so, so tolerance checks are exact.
End-to-end tests use the real UAVTalk driver and simulator instead.
"""

from __future__ import annotations

import threading

from onboard.fc.base import FlightControllerError, StateHolder, VehicleState
from onboard.navigation import ned_to_lla

HOME = (40.6303, -8.6575, 12.0)


class FakeFlightController:
    protocol = "fake"

    def __init__(self, *, refuse_arm: bool = False) -> None:
        self._state = StateHolder(
            VehicleState(protocol="fake", connected=True, home=HOME, gps_fix=True)
        )
        self.refuse_arm = refuse_arm
        self.calls: list[tuple] = []
        self.listeners = []
        self.moved = threading.Event()
        self.move_to(0.0, 0.0, 0.0)

    @property
    def state(self) -> VehicleState:
        return self._state.get()

    def move_to(self, north: float, east: float, down: float) -> None:
        lat, lon, alt_msl = ned_to_lla(north, east, down, HOME)
        self._state.update(ned=(north, east, down), lat=lat, lon=lon, alt=alt_msl - HOME[2])
        self.moved.set()

    def set_battery(self, remaining: float) -> None:
        self._state.update(battery_remaining=remaining, battery_voltage=14.0 + 2.4 * remaining)

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def add_listener(self, listener) -> None:
        self.listeners.append(listener)

    def wait_connected(self, timeout: float) -> bool:
        return True

    def arm(self, timeout: float = 10.0) -> None:
        self.calls.append(("arm",))
        if self.refuse_arm:
            raise FlightControllerError("The flight controller did not arm (alarm active)")
        self._state.update(armed=True)

    def disarm(self, timeout: float = 10.0) -> None:
        self.calls.append(("disarm",))
        self._state.update(armed=False)

    def goto_ned(self, north: float, east: float, down: float) -> None:
        self.calls.append(("goto", north, east, down))

    def takeoff(self, altitude: float) -> None:
        self.calls.append(("takeoff", altitude))

    def land(self) -> None:
        self.calls.append(("land",))

    def request_object(self, name: str, timeout: float = 2.0) -> dict:
        if name != "FlightStatus":
            raise FlightControllerError(f"The flight controller has no object {name}")
        return {"Armed": "Armed" if self.state.armed else "Disarmed"}

    def write_object(
        self, name: str, fields: dict, timeout: float = 2.0, *, acked: bool = True
    ) -> None:
        self.calls.append(("write", name, fields))

    def rebuild_link(self) -> None:
        self.calls.append(("rebuild",))

    def reset(self) -> None:
        self.calls.append(("reset",))

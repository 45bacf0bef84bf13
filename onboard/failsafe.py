"""Fail-safe System: low battery, out-of-bounds readings and a lost ground link.

- Battery under the threshold → exactly one CRITICAL alarm (the ground replaces the
  drone); it re-arms only once the battery is back above the threshold plus a margin
  (a new battery), so a noisy voltage never floods the ground.
- A sensor reading outside its configured bounds → one OUT_MEASURE alarm when the sensor
  goes out of bounds (the ground extends the mission around that position).
- Ground link lost for N seconds while airborne → the configured action: `continue`
  (the mission goes on, the default), `hold`, `return` (home, same altitude) or `land`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from .fc.base import FlightController
from .navigation import NavigationProcessor, current_ned

log = logging.getLogger(__name__)

LINK_LOSS_ACTIONS = ("continue", "hold", "return", "land")
BATTERY_REARM_MARGIN = 0.10

# raise_alarm(level, message, *, sensor=None, value=None, context=None)
RaiseAlarm = Callable[..., None]


class FailSafe:
    def __init__(
        self,
        fc: FlightController,
        raise_alarm: RaiseAlarm,
        *,
        navigation: NavigationProcessor | None = None,
        stop_mission: Callable[[str], bool] | None = None,
        battery_critical: float = 0.25,
        bounds: dict[str, tuple[float | None, float | None]] | None = None,
        link_loss_timeout: float = 30.0,
        link_loss_action: str = "continue",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if link_loss_action not in LINK_LOSS_ACTIONS:
            raise ValueError(f"link loss action must be one of {', '.join(LINK_LOSS_ACTIONS)}")
        self.fc = fc
        self.raise_alarm = raise_alarm
        self.navigation = navigation
        self.stop_mission = stop_mission or (lambda reason: False)
        self.battery_critical = battery_critical
        self.bounds = dict(bounds or {})
        self.link_loss_timeout = link_loss_timeout
        self.link_loss_action = link_loss_action
        self.clock = clock
        self.alarms_raised = 0
        self.link_actions_taken: list[str] = []
        self._lock = threading.Lock()
        self._battery_alarmed = False
        self._out_of_bounds: set[str] = set()
        self._link_lost_at: float | None = None
        self._link_acted = False

    # -- battery --------------------------------------------------------------------------

    def check_battery(self) -> bool:
        """Raise the CRITICAL alarm once when the battery crosses the threshold."""
        remaining = self.fc.state.battery_remaining
        if remaining is None:
            return False
        with self._lock:
            if self._battery_alarmed:
                if remaining > self.battery_critical + BATTERY_REARM_MARGIN:
                    self._battery_alarmed = False
                return False
            if remaining >= self.battery_critical:
                return False
            self._battery_alarmed = True
        self.alarms_raised += 1
        self.raise_alarm(
            "CRITICAL",
            f"battery below {self.battery_critical * 100:.0f} % ({remaining * 100:.0f} % left)",
            sensor="battery",
            value=remaining,
        )
        return True

    # -- sensor bounds --------------------------------------------------------------------

    def check_reading(self, sensor: str, reading: dict) -> bool:
        """OUT_MEASURE once when a sensor leaves its bounds; again only after it came back."""
        bounds = self.bounds.get(sensor)
        value = reading.get("value")
        if bounds is None or not isinstance(value, int | float):
            return False
        lo, hi = bounds
        outside = (lo is not None and value < lo) or (hi is not None and value > hi)
        with self._lock:
            if not outside:
                self._out_of_bounds.discard(sensor)
                return False
            if sensor in self._out_of_bounds:
                return False
            self._out_of_bounds.add(sensor)
        self.alarms_raised += 1
        context = {k: reading[k] for k in ("mission_id", "assignment_id", "index") if k in reading}
        self.raise_alarm(
            "OUT_MEASURE",
            f"{sensor} reading {value:g} outside [{_fmt(lo, '-inf')}, {_fmt(hi, 'inf')}]",
            sensor=sensor,
            value=float(value),
            context=context or None,
        )
        return True

    # -- ground link ----------------------------------------------------------------------

    def link_changed(self, connected: bool) -> None:
        with self._lock:
            if connected:
                self._link_lost_at = None
                self._link_acted = False
            elif self._link_lost_at is None:
                self._link_lost_at = self.clock()

    def check_link(self) -> str | None:
        """Apply the link-loss action once the link has been down long enough while airborne."""
        with self._lock:
            lost_at, acted = self._link_lost_at, self._link_acted
        if lost_at is None or acted or self.link_loss_action == "continue":
            return None
        if self.clock() - lost_at < self.link_loss_timeout or not self.fc.state.airborne:
            return None
        with self._lock:
            self._link_acted = True
        action = self.link_loss_action
        log.warning("ground link lost for %.0f s: %s", self.clock() - lost_at, action)
        self.stop_mission(f"ground link lost; fail-safe {action}")
        state = self.fc.state
        try:
            if action == "land":
                self.fc.land()
            else:
                here = current_ned(state) or (0.0, 0.0, 0.0)
                point = here if action == "hold" else (0.0, 0.0, here[2])
                if self.navigation is not None:
                    self.navigation.hold_at(point)
                else:
                    self.fc.goto_ned(*point)
        except Exception:
            log.exception("fail-safe %s failed", action)
        self.link_actions_taken.append(action)
        return action

    def tick(self) -> None:
        self.check_battery()
        self.check_link()


def _fmt(value: float | None, unbounded: str) -> str:
    return unbounded if value is None else f"{value:g}"


def parse_bounds(text: str) -> tuple[str, tuple[float | None, float | None]]:
    """CLI form `SENSOR:LO:HI` (either side may be empty) → (sensor, (lo, hi))."""
    parts = text.split(":")
    if len(parts) != 3 or not parts[0]:
        raise ValueError("bounds are SENSOR:LO:HI, e.g. CO2::1000")
    lo = float(parts[1]) if parts[1] else None
    hi = float(parts[2]) if parts[2] else None
    return parts[0], (lo, hi)

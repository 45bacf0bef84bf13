"""Fail-safe System: low battery, out-of-bounds readings, a lost ground link, and what a
drone does on its own once a mission ends or the ground is gone.

- Battery under the threshold → a CRITICAL alarm, repeated until the ground acknowledges
  it; when the ground has not taken over (a control command or a mission request) within
  `critical_takeover` seconds, the drone returns home and lands. It re-arms only once the
  battery is back above the threshold plus a margin (a new battery).
- A sensor reading outside its configured bounds → one OUT_MEASURE alarm when the sensor
  goes out of bounds (the ground extends the mission around that position).
- Ground link lost for N seconds while airborne → the configured action: `return` (the
  default: home at the same altitude, land, disarm), `hold` (hover; return once the
  battery reaches the reserve), `land` (here) or `continue` (the mission goes on).
- Every return flies home inside the altitude band of the drone's reservation when the
  ground relayed one (onboard/traffic.py): the band is kept while the ground is not heard.
- Every return lands where the drone is instead when the energy left would not get it
  home: distance ÷ return speed × the drain measured in flight.
- A completed mission leaves the drone on the ground and disarmed (home, land); a stopped
  one leaves it holding where it is until the operator decides.
- Landed and still armed for `auto_disarm_delay` seconds → disarm, as PX4 does
  (COM_DISARM_LAND, 2 s by default).

Waits on the ground (link-loss timeout, alarm repeat, takeover) are wall seconds: the
ground runs in real time. What the flight decides (the auto-disarm delay, the measured
drain) is in flight seconds: wall seconds × the agent's time scale in simulation.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from .fc.base import FlightController, VehicleState
from .navigation import NavigationProcessor, current_ned
from .traffic import inside_band

log = logging.getLogger(__name__)

LINK_LOSS_ACTIONS = ("continue", "hold", "return", "land")
BATTERY_REARM_MARGIN = 0.10
# Over home within this many metres (horizontally) → land.
HOME_RADIUS_M = 2.0
# A return that first moves into the reservation's band goes on home once this close
# (vertically, metres) to the band's edge.
BAND_REACHED_M = 1.0
# The drain is measured over this many flight seconds of battery readings.
DRAIN_WINDOW_S = 30.0
# Descent speed assumed for the landing part of the energy estimate, m/s.
DESCENT_SPEED = 1.5

# raise_alarm(level, message, *, sensor=None, value=None, context=None)
RaiseAlarm = Callable[..., None]


@dataclass(frozen=True)
class Limits:
    """The fail-safe's thresholds and delays: the ground's waits in wall seconds, the
    auto-disarm delay in flight seconds."""

    battery_critical: float = 0.25
    # A holding drone returns once the battery is down to this.
    battery_reserve: float = 0.30
    # The CRITICAL alarm is sent again this often until the ground acknowledges it.
    alarm_repeat: float = 10.0
    # The ground has this long after a CRITICAL alarm to take over before the drone returns.
    critical_takeover: float = 30.0
    link_loss_timeout: float = 30.0
    link_loss_action: str = "return"
    return_speed: float = 5.0
    auto_disarm_delay: float = 2.0

    def __post_init__(self) -> None:
        if self.link_loss_action not in LINK_LOSS_ACTIONS:
            raise ValueError(f"link loss action must be one of {', '.join(LINK_LOSS_ACTIONS)}")
        if self.return_speed <= 0:
            raise ValueError("the return speed must be positive")


class DrainMeter:
    """The battery fraction used per flight second, from readings taken while airborne."""

    def __init__(self, window: float = DRAIN_WINDOW_S) -> None:
        self.window = window
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, now: float, remaining: float) -> None:
        self._samples.append((now, remaining))
        while self._samples and now - self._samples[0][0] > self.window:
            self._samples.popleft()

    def reset(self) -> None:
        self._samples.clear()

    @property
    def rate(self) -> float | None:
        """Fraction per second, or None before a few seconds of readings."""
        if len(self._samples) < 2:
            return None
        (t0, r0), (t1, r1) = self._samples[0], self._samples[-1]
        if t1 - t0 < min(2.0, self.window / 2):
            return None
        return max(0.0, (r0 - r1) / (t1 - t0))


def energy_to_get_home(state: VehicleState, drain_per_s: float, speed: float) -> float | None:
    """The battery fraction a flight home and a landing would take, or None when unknown."""
    here = current_ned(state)
    if here is None:
        return None
    seconds = math.hypot(here[0], here[1]) / speed + max(0.0, -here[2]) / DESCENT_SPEED
    return seconds * drain_per_s


@dataclass
class CriticalAlarm:
    """One low-battery episode: when it began, when it was last sent, what the ground did."""

    raised_at: float
    sent_at: float
    acknowledged: bool = False
    taken_over: bool = False
    returned: bool = False


class FailSafe:
    def __init__(
        self,
        fc: FlightController,
        raise_alarm: RaiseAlarm,
        *,
        navigation: NavigationProcessor | None = None,
        stop_mission: Callable[[str], bool] | None = None,
        bounds: dict[str, tuple[float | None, float | None]] | None = None,
        limits: Limits | None = None,
        time_scale: float = 1.0,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.fc = fc
        self.raise_alarm = raise_alarm
        self.navigation = navigation
        self.stop_mission = stop_mission or (lambda reason: False)
        self.bounds = dict(bounds or {})
        self.limits = limits or Limits()
        self.clock = clock or time.monotonic  # wall seconds
        # The simulator's time runs time_scale times faster than the wall's.
        self.time_scale = time_scale
        self.alarms_raised = 0
        self.actions_taken: list[str] = []
        # What the fail-safe is doing with the drone: "return", "land", "hold" or None.
        self.recovery: str | None = None
        self.drain = DrainMeter()
        # What a mission stopped by the ground leaves the drone doing (the stop's `then`);
        # None once a command received after the stop has overtaken it.
        self.after_stop: str | None = "hold"
        # A stop has been received and its mission has not wound down yet.
        self._stop_pending = False
        self._lock = threading.Lock()
        # Held while the fail-safe decides and sends a take-over's commands (the mission
        # thread at a mission's end, the supervisor's tick): a decision made on another
        # thread in between (over home: land) would reach the drone before the command
        # it follows (the return's goto) and be overwritten by it.
        self._commanding = threading.RLock()
        self._critical: CriticalAlarm | None = None
        self._out_of_bounds: set[str] = set()
        self._link_lost_at: float | None = None
        self._link_acted = False
        self._was_airborne = False
        self._landed_at: float | None = None
        # The altitude band (metres above home) of the drone's reservation, as the ground
        # last relayed it (onboard/traffic.py); kept while the ground is not heard, so a
        # return never leaves it before it is over home. None: no band known.
        self.band: tuple[float, float] | None = None
        self._band_first: tuple[float, float, float] | None = None

    # -- battery --------------------------------------------------------------------------

    def check_battery(self) -> bool:
        """Raise the CRITICAL alarm when the battery crosses the threshold; True if it did."""
        state = self.fc.state
        remaining = state.battery_remaining
        if remaining is None:
            return False
        now = self.clock()
        if state.airborne:
            self.drain.add(now * self.time_scale, remaining)
        critical = self.limits.battery_critical
        with self._lock:
            alarm = self._critical
            if alarm is not None and remaining > critical + BATTERY_REARM_MARGIN:
                self._critical = None  # a new battery
                return False
            if alarm is None and remaining < critical:
                self._critical = CriticalAlarm(now, now)
        if alarm is None and self._critical is not None:
            self._send_critical(remaining, repeated=False)
            return True
        if alarm is not None:
            self._follow_up(alarm, now, remaining)
        return False

    def _send_critical(self, remaining: float, *, repeated: bool) -> None:
        self.alarms_raised += 1
        again = " (repeated until acknowledged)" if repeated else ""
        self.raise_alarm(
            "CRITICAL",
            f"battery below {self.limits.battery_critical * 100:.0f} % "
            f"({remaining * 100:.0f} % left){again}",
            sensor="battery",
            value=remaining,
        )

    def _follow_up(self, alarm: CriticalAlarm, now: float, remaining: float) -> None:
        """Repeat an unacknowledged alarm; return once the ground let the takeover time pass."""
        if not alarm.acknowledged and now - alarm.sent_at >= self.limits.alarm_repeat:
            alarm.sent_at = now
            self._send_critical(remaining, repeated=True)
        if alarm.taken_over or alarm.returned or not self.fc.state.airborne:
            return
        if now - alarm.raised_at >= self.limits.critical_takeover:
            alarm.returned = True
            self.return_home("battery critical and the ground has not taken over")

    def acknowledge(self, level: str) -> bool:
        """The ground has the alarm: stop repeating it. False when none is pending."""
        with self._lock:
            alarm = self._critical
            if level != "CRITICAL" or alarm is None or alarm.acknowledged:
                return False
            alarm.acknowledged = True
        log.info("CRITICAL alarm acknowledged by the ground")
        return True

    def ground_took_over(self) -> None:
        """The ground sent a command or a mission: the operator decides from now on.
        A command received after a stop overtakes the stop's follow-up: the stopped
        mission may wind down after the command has flown (they run on different
        threads), and a hold then would undo the operator's landing."""
        with self._lock:
            if self._critical is not None:
                self._critical.taken_over = True
            self.recovery = None
            self.after_stop = None if self._stop_pending else "hold"

    def mission_requested(self) -> None:
        """A new mission from the ground: no earlier stop is pending any more."""
        with self._lock:
            self._stop_pending = False
        self.ground_took_over()

    def stop_requested(self, follow_up: str) -> None:
        """The ground stopped the mission; `follow_up` is what the drone does once it
        has wound down, unless a command overtakes it. Not a take-over: a late stop for
        a mission the fail-safe already ended must not leave a returning drone hovering."""
        with self._lock:
            self.after_stop = follow_up
            self._stop_pending = True

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
        action = self.limits.link_loss_action
        with self._lock:
            lost_at, acted = self._link_lost_at, self._link_acted
        if lost_at is None or acted or action == "continue":
            return None
        if self.clock() - lost_at < self.limits.link_loss_timeout or not self.fc.state.airborne:
            return None
        with self._lock:
            self._link_acted = True
        log.warning("ground link lost for %.0f s: %s", self.clock() - lost_at, action)
        reason = f"ground link lost; fail-safe {action}"
        taken = {"land": self.land_here, "hold": self.hold_here, "return": self.return_home}
        done = taken[action](reason)
        self.actions_taken.append(f"link:{action}")
        return done

    # -- taking the drone over ------------------------------------------------------------

    def return_home(self, reason: str) -> str:
        """Home at the current altitude, then land; land here when the energy would not do."""
        state = self.fc.state
        short = self.energy_shortfall(state)
        if short is not None:
            return self.land_here(f"{reason}; not enough energy left to get home ({short})")
        here = current_ned(state) or (0.0, 0.0, 0.0)
        # Home at this height; outside the reservation's band (when one is known: the
        # airspace the ground keeps other drones out of), first straight up or down into
        # it where the drone is, then home inside it.
        height = inside_band(-here[2], self.band)
        first = (here[0], here[1], -height) if abs(height + here[2]) > BAND_REACHED_M else None
        self._band_first = first
        self._take_over("return", reason, lambda: self._goto(first or (0.0, 0.0, -height)))
        return "return"

    def land_here(self, reason: str) -> str:
        self._take_over("land", reason, self._land)
        return "land"

    def hold_here(self, reason: str) -> str:
        here = current_ned(self.fc.state) or (0.0, 0.0, 0.0)
        self._take_over("hold", reason, lambda: self._goto(here))
        return "hold"

    def energy_shortfall(self, state: VehicleState) -> str | None:
        """Why the measured drain says the battery would run out on the way home, or None
        (also when the drain is not known yet: then the drone tries)."""
        rate, remaining = self.drain.rate, state.battery_remaining
        if rate is None or remaining is None:
            return None
        need = energy_to_get_home(state, rate, self.limits.return_speed)
        if need is None or need <= remaining:
            return None
        return f"needs {need * 100:.0f} %, has {remaining * 100:.0f} %"

    def _take_over(self, mode: str, reason: str, fly: Callable[[], None]) -> None:
        with self._commanding:
            # Set before stopping the mission: the stopped mission must not re-plan the drone.
            with self._lock:
                self.recovery = mode
            log.warning("fail-safe %s: %s", mode, reason)
            self.stop_mission(reason)
            try:
                fly()
            except Exception:
                log.exception("fail-safe %s failed", mode)
            self.actions_taken.append(mode)

    def _goto(self, point: tuple[float, float, float]) -> None:
        if self.navigation is not None:
            self.navigation.hold_at(point)
        else:
            self.fc.goto_ned(*point)

    def _land(self) -> None:
        if self.navigation is not None:
            self.navigation.execute("land", {})
        else:
            self.fc.land()

    def check_recovery(self) -> None:
        """Land once a returning drone is over home; a holding one returns at the reserve.
        While a take-over is still sending its commands, the next tick judges."""
        if not self._commanding.acquire(blocking=False):
            return
        try:
            self._advance_recovery()
        finally:
            self._commanding.release()

    def _advance_recovery(self) -> None:
        state = self.fc.state
        mode = self.recovery
        if mode is not None and not state.armed:
            self.recovery = None
        elif mode == "return" and self._band_first is not None:
            here = current_ned(state)
            if here is not None and abs(here[2] - self._band_first[2]) <= BAND_REACHED_M:
                self._goto((0.0, 0.0, self._band_first[2]))
                self._band_first = None
        elif mode == "return":
            here = current_ned(state)
            if here is not None and math.hypot(here[0], here[1]) <= HOME_RADIUS_M:
                self.recovery = "land"
                self._land()
                self.actions_taken.append("land")
        elif mode == "hold":
            remaining = state.battery_remaining
            if remaining is not None and remaining <= self.limits.battery_reserve:
                self.return_home("battery reserve reached while holding")

    # -- mission end and landing ----------------------------------------------------------

    def mission_ended(self, status: str) -> None:
        """A completed mission ends on the ground, disarmed; a stopped one holds in place."""
        state = self.fc.state
        follow_up = self._take_follow_up() if status == "stopped" else None
        if self.recovery is not None or not state.armed:
            return
        if status == "completed" and state.airborne and not self._landing():
            self.return_home("the mission is complete")
        elif status == "completed" and not state.airborne:
            self._disarm("the mission is complete")
        elif status == "stopped" and state.airborne:
            self._after_stop(follow_up)

    def _take_follow_up(self) -> str | None:
        """The stop's follow-up, once: the next mission's stop says its own."""
        with self._lock:
            follow_up, self.after_stop = self.after_stop, "hold"
            self._stop_pending = False
        return follow_up

    def _after_stop(self, follow_up: str | None) -> None:
        if follow_up is None:
            log.info("mission stopped: the command sent after the stop stands")
        elif follow_up == "return":
            self.return_home("the mission was stopped with a return")
        elif follow_up == "land":
            self.land_here("the mission was stopped with a landing")
        else:
            self.hold_here("the mission was stopped; waiting for the operator")

    def _landing(self) -> bool:
        """The last target asked for is a landing (auto-disarm finishes the job)."""
        target = self.navigation.last_target if self.navigation is not None else None
        return target is not None and target.kind == "land"

    def arm_requested(self) -> None:
        """An arm asked for on the ground is for a new flight, not the tail of a landing:
        the landing's auto-disarm no longer applies (a disarm and the next arm may both
        fall between two ticks, which would not see the drone disarmed in between)."""
        with self._commanding:
            self._was_airborne = False
            self._landed_at = None

    def check_landed(self) -> bool:
        """Disarm a drone that has sat landed and armed for the auto-disarm delay."""
        with self._commanding:
            return self._check_landed()

    def _check_landed(self) -> bool:
        state = self.fc.state
        if state.airborne or not state.armed:
            self._was_airborne = state.airborne
            self._landed_at = None
            return False
        if not self._was_airborne:
            return False  # armed on the ground before a take-off
        now = self.clock()
        if self._landed_at is None:
            self._landed_at = now
        if (now - self._landed_at) * self.time_scale < self.limits.auto_disarm_delay:
            return False
        self._was_airborne = False
        self._landed_at = None
        return self._disarm("landed")

    def _disarm(self, reason: str) -> bool:
        log.info("auto-disarm: %s", reason)
        try:
            self.fc.disarm()
        except Exception:
            log.exception("auto-disarm failed")
            return False
        self.actions_taken.append("disarm")
        return True

    def tick(self) -> None:
        if not self.fc.state.armed:
            self.band = None  # a band is one flight's
        self.check_battery()
        self.check_link()
        self.check_recovery()
        self.check_landed()


class GroundClock:
    """How far this drone's clock runs ahead of the ground's, learnt from the ground's own
    timestamps, and so how old a request really is.

    Every request carries its issue time on the ground's clock; arrival − issue time is the
    clock offset plus the time on the way. The smallest such sample over the last
    `window` seconds is the offset plus the quickest delivery (NTP's minimum filter): a
    request queued while the drone was away arrives late, so it only makes its own sample
    larger, never the estimate. Until a first request arrives the offset is unknown and
    that first request is its own reference (age 0): an unknown clock never refuses.
    """

    def __init__(
        self,
        window: float = 3600.0,
        clock: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.window = window
        self.clock = clock
        self.monotonic = monotonic
        self._samples: deque[tuple[float, float]] = deque()
        self._lock = threading.Lock()

    def age(self, issued: float) -> float:
        """Seconds since the ground issued a request (this request also teaches the offset)."""
        sample = self.clock() - issued
        now = self.monotonic()
        with self._lock:
            self._samples.append((now, sample))
            while now - self._samples[0][0] > self.window:
                self._samples.popleft()
            offset = min(s for _, s in self._samples)
        return sample - offset

    @property
    def offset(self) -> float | None:
        """This clock minus the ground's (plus the quickest delivery), None before a request."""
        with self._lock:
            return min((s for _, s in self._samples), default=None)


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

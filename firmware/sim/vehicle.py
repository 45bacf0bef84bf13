"""The simulated multicopter: pure state and `step(dt)`, no I/O, no wall clock.

Everything here runs on simulated seconds. The server feeds it receiver frames and the
objects a ground station writes, steps it, and reads its state to build telemetry.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from firmware.sim.receiver import ARMED, ARMING, DISARMED, ReceiverArming

# One LLA↔NED for the whole project: the sphere dRonin linearises about home (docs/uavtalk.md).
from onboard.navigation import euler_to_quaternion, lla_to_ned, ned_to_lla

log = logging.getLogger(__name__)

AUTONOMOUS_MODES = ("PositionHold", "PathPlanner", "ReturnToHome", "TabletControl")
# The part of the wind's speed the position controller does not hold against in the air:
# the vehicle is pushed downwind at this fraction of it and flies back (the simulator's own
# figure, so a wind shows as a small drift, not a new flight model).
WIND_DRIFT_FRACTION = 0.1
# 4S LiPo open-circuit voltage per cell against charge left (fraction), coarse but monotonic.
CELL_CURVE = ((0.0, 3.30), (0.05, 3.50), (0.2, 3.68), (0.5, 3.80), (0.8, 3.98), (1.0, 4.20))


@dataclass
class VehicleConfig:
    home: tuple[float, float, float] = (38.736, -9.138, 100.0)  # lat, lon, alt MSL
    max_climb: float = 2.0  # m/s
    max_descent: float = 2.0  # m/s
    max_horizontal: float = 10.0  # m/s
    horizontal_accel: float = 3.0  # m/s²
    vertical_accel: float = 2.0  # m/s²
    battery_capacity_mah: float = 5500.0
    cells: int = 4
    hover_drain_mah_s: float = 15_000 / 3600  # 15 A while hovering
    flying_drain_per_mps: float = 0.03  # extra fraction of hover drain per m/s of speed
    idle_current_a: float = 0.4  # disarmed electronics
    ground_armed_current_a: float = 3.0  # motors idling on the ground
    internal_resistance_ohm: float = 0.02
    satellites: int = 12
    max_yaw_rate: float = 60.0  # deg/s a multirotor turns its nose at in autonomous flight


def interpolate(curve: Sequence[tuple[float, float]], x: float) -> float:
    x = min(max(x, curve[0][0]), curve[-1][0])
    for (x0, y0), (x1, y1) in zip(curve, curve[1:], strict=False):
        if x <= x1:
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    return curve[-1][1]


@dataclass
class PathTarget:
    mode: str = "HoldPosition"  # PathDesired mode: Endpoint, HoldPosition, Land, ...
    end: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class Vehicle:
    config: VehicleConfig = field(default_factory=VehicleConfig)
    receiver: ReceiverArming = field(default_factory=ReceiverArming)
    time: float = 0.0  # simulated seconds since boot
    ned: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    velocity: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    yaw: float = 0.0  # degrees
    flight_mode: str = "Manual"
    target: PathTarget = field(default_factory=PathTarget)
    consumed_mah: float = 0.0
    current_a: float = 0.0
    peak_current_a: float = 0.0
    home: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # Waypoint instances (mode, NED) the path planner flies in order, and where it is.
    waypoints: dict[int, tuple[str, tuple[float, float, float]]] = field(default_factory=dict)
    plan_index: int | None = None
    # A region of interest (north, east in m from home) the nose points at while flying;
    # None: the nose follows the direction of travel.
    roi: tuple[float, float] | None = None
    # The air's velocity, m/s North-East-Down (firmware/sim/wind.py sets it).
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        self.home = self.config.home

    # --- inputs -----------------------------------------------------------------------
    @property
    def armed(self) -> str:
        return self.receiver.state

    @property
    def airborne(self) -> bool:
        return self.ned[2] < -0.3

    def feed_receiver(self, pulses_us: Sequence[int]) -> str:
        """One receiver frame (pulse widths); returns the arming state after it."""
        self.receiver.airborne = self.airborne
        before = self.receiver.state
        state = self.receiver.feed(pulses_us, self.time)
        if before != ARMED and state == ARMED:
            # Freshly armed: hold where it stands until told otherwise.
            self.target = PathTarget("HoldPosition", (self.ned[0], self.ned[1], self.ned[2]))
            if self.flight_mode not in AUTONOMOUS_MODES:
                self.flight_mode = "PositionHold"
        return state

    def set_flight_mode(self, mode: str) -> None:
        self.flight_mode = mode
        if mode == "ReturnToHome":
            self.target = PathTarget("Endpoint", (0.0, 0.0, min(self.ned[2], -10.0)))

    def set_waypoint(self, instance: int, mode: str, position: Sequence[float]) -> None:
        """A Waypoint write: the path planner (re)starts from instance 0 in PathPlanner mode."""
        north, east, down = (float(v) for v in position)
        self.waypoints[instance] = (mode, (north, east, down))
        self.plan_index = 0

    def set_path_desired(self, mode: str, end: Sequence[float]) -> None:
        """A direct PathDesired write replaces any waypoint plan."""
        self.plan_index = None
        north, east, down = (float(v) for v in end)
        if mode == "Land":
            down = 0.0
        self.target = PathTarget(mode, (north, east, min(down, 0.0)))
        # One line per setpoint, stamped with the wall clock: a benchmark times a command
        # from the ground to this moment (bench/bench_teleop.py).
        log.info("setpoint %s %.3f %.3f %.3f at %.6f", mode, *self.target.end, time.time())

    def set_home(self, lat: float, lon: float, alt: float) -> None:
        """Move home; the vehicle stays where it is on the globe, so its NED changes."""
        here = self.lla()
        self.home = (lat, lon, alt)
        self.ned = list(lla_to_ned(*here, self.home))

    def reboot(self) -> None:
        """State after a reset: disarmed, on the ground where it is, home kept."""
        self.receiver.reset()
        self.time = 0.0
        self.velocity = [0.0, 0.0, 0.0]
        self.ned[2] = 0.0
        self.flight_mode = "Manual"
        self.roi = None
        self.target = PathTarget("HoldPosition", (self.ned[0], self.ned[1], 0.0))

    # --- dynamics ---------------------------------------------------------------------
    def step(self, dt: float) -> None:
        if dt <= 0:
            return
        self.time += dt
        if self.receiver.state == ARMED and self.flight_mode in AUTONOMOUS_MODES:
            self._fly(dt)
            self._drift(dt)
        else:
            self._fall_or_rest(dt)
        self._drain(dt)

    def _drift(self, dt: float) -> None:
        """In the air, the wind pushes the vehicle a little downwind (WIND_DRIFT_FRACTION)."""
        if self.airborne:
            self.ned[0] += self.wind[0] * WIND_DRIFT_FRACTION * dt
            self.ned[1] += self.wind[1] * WIND_DRIFT_FRACTION * dt

    def _follow_plan(self) -> None:
        """PathPlanner: feed Waypoint instances to the path follower until the first Invalid."""
        if self.flight_mode != "PathPlanner" or self.plan_index is None:
            return
        waypoint = self.waypoints.get(self.plan_index)
        if waypoint is None or waypoint[0] == "Invalid":
            self.plan_index = None  # plan done: hold the last target
            return
        mode, (north, east, down) = waypoint
        self.target = PathTarget(mode, (north, east, 0.0 if mode == "Land" else min(down, 0.0)))
        gap = math.dist(self.ned, self.target.end)
        if gap < 1.0 and mode not in ("Land", "HoldPosition"):
            self.plan_index += 1

    def _fly(self, dt: float) -> None:
        self._follow_plan()
        cfg = self.config
        tn, te, td = self.target.end
        if self.target.mode == "Land":
            # Over the landing spot first, then descend.
            horizontal_gap = math.hypot(tn - self.ned[0], te - self.ned[1])
            td = self.ned[2] if horizontal_gap > 1.0 else 0.0
        dn, de = tn - self.ned[0], te - self.ned[1]
        dist = math.hypot(dn, de)
        # Speed that still lets it stop at the target: v = sqrt(2 a d), capped.
        speed = min(cfg.max_horizontal, math.sqrt(2 * cfg.horizontal_accel * dist))
        want_n, want_e = (dn / dist * speed, de / dist * speed) if dist > 1e-6 else (0.0, 0.0)
        dd = td - self.ned[2]
        vspeed = math.sqrt(2 * cfg.vertical_accel * abs(dd))
        want_d = math.copysign(min(vspeed, cfg.max_descent if dd > 0 else cfg.max_climb), dd)
        self.velocity[0] = _approach(self.velocity[0], want_n, cfg.horizontal_accel * dt)
        self.velocity[1] = _approach(self.velocity[1], want_e, cfg.horizontal_accel * dt)
        self.velocity[2] = _approach(self.velocity[2], want_d, cfg.vertical_accel * dt)
        for axis, goal in ((0, tn), (1, te), (2, td)):
            before = goal - self.ned[axis]
            self.ned[axis] += self.velocity[axis] * dt
            after = goal - self.ned[axis]
            if before * after < 0:  # crossed the goal this step: no overshoot
                self.ned[axis] = goal
                self.velocity[axis] = 0.0
        if self.ned[2] > 0.0:
            self.ned[2] = 0.0
            self.velocity[2] = 0.0
        self._turn(dt)

    def _turn(self, dt: float) -> None:
        """Yaw toward the region of interest at the yaw rate limit, or else, on a leg to an
        endpoint, along the horizontal velocity, as autopilots face the next waypoint;
        holding or landing keeps the heading, whatever drift is left."""
        if self.roi is not None:
            dn, de = self.roi[0] - self.ned[0], self.roi[1] - self.ned[1]
            if math.hypot(dn, de) < 0.5:
                return  # straight above it: any heading faces it
            goal = math.degrees(math.atan2(de, dn)) % 360.0
            error = (goal - self.yaw + 180.0) % 360.0 - 180.0
            turn = max(-self.config.max_yaw_rate * dt, min(self.config.max_yaw_rate * dt, error))
            self.yaw = (self.yaw + turn) % 360.0
        elif self.target.mode == "Endpoint" and self._far_from_endpoint():
            self.yaw = math.degrees(math.atan2(self.velocity[1], self.velocity[0])) % 360.0

    def _far_from_endpoint(self) -> bool:
        """Whether the nose still follows the leg: moving fast enough for a direction to mean
        anything and more than 2 m short of the endpoint (ArduCopter's WPNAV_YAW_DIST_MIN;
        PX4 likewise keeps the heading inside the acceptance radius), so arriving, or the
        end of a region of interest near the endpoint, never swings the nose."""
        remaining = math.hypot(self.target.end[0] - self.ned[0], self.target.end[1] - self.ned[1])
        return math.hypot(*self.velocity[:2]) > 0.5 and remaining > 2.0

    def _fall_or_rest(self, dt: float) -> None:
        # Not flying autonomously: come down (motors stop when disarmed on the ground).
        self.velocity[0] = _approach(self.velocity[0], 0.0, self.config.horizontal_accel * dt)
        self.velocity[1] = _approach(self.velocity[1], 0.0, self.config.horizontal_accel * dt)
        self.velocity[2] = self.config.max_descent if self.ned[2] < 0 else 0.0
        for axis in range(3):
            self.ned[axis] += self.velocity[axis] * dt
        if self.ned[2] >= 0.0:
            self.ned[2] = 0.0
            self.velocity = [0.0, 0.0, 0.0]

    def _drain(self, dt: float) -> None:
        cfg = self.config
        hover_a = cfg.hover_drain_mah_s * 3.6
        if self.receiver.state != ARMED:
            current = cfg.idle_current_a
        elif not self.airborne:
            current = cfg.ground_armed_current_a
        else:
            speed = math.sqrt(sum(v * v for v in self.velocity))
            current = hover_a * (1.0 + cfg.flying_drain_per_mps * speed)
        self.current_a = current
        self.peak_current_a = max(self.peak_current_a, current)
        self.consumed_mah = min(cfg.battery_capacity_mah, self.consumed_mah + current * dt / 3.6)

    # --- outputs ----------------------------------------------------------------------
    @property
    def remaining(self) -> float:
        return max(0.0, 1.0 - self.consumed_mah / self.config.battery_capacity_mah)

    @property
    def voltage(self) -> float:
        cell = interpolate(CELL_CURVE, self.remaining)
        return self.config.cells * cell - self.current_a * self.config.internal_resistance_ohm

    def estimated_flight_time(self) -> float:
        left_mah = self.config.battery_capacity_mah - self.consumed_mah
        return left_mah * 3.6 / max(self.current_a, 0.1)

    def lla(self) -> tuple[float, float, float]:
        return ned_to_lla(self.ned[0], self.ned[1], self.ned[2], self.home)

    def attitude(self) -> tuple[float, float, float]:
        """Roll, pitch, yaw in degrees: tilt into the horizontal velocity, as a multirotor does."""
        yaw = math.radians(self.yaw)
        forward = self.velocity[0] * math.cos(yaw) + self.velocity[1] * math.sin(yaw)
        right = -self.velocity[0] * math.sin(yaw) + self.velocity[1] * math.cos(yaw)
        return (right * 1.5, -forward * 1.5, self.yaw)

    def status(self) -> str:
        return self.receiver.state


def _approach(value: float, goal: float, max_change: float) -> float:
    if value < goal:
        return min(goal, value + max_change)
    return max(goal, value - max_change)


__all__ = ["ARMED", "ARMING", "DISARMED", "Vehicle", "VehicleConfig", "euler_to_quaternion"]

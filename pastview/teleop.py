"""Teleoperation from the past-view page: stick input to small relative moves.

The page sends stick deflections in the drone's own frame (forward, right, up; each
-1..1). One move is at most ``step_m`` along each axis, turned into the North/East
commands of docs/protocol.md by the drone's heading. Relative commands add to the last target
(onboard/navigation.py), so small steps at a bounded rate keep the target at most one
step ahead of the drone: when input stops, the drone stops within a step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Smaller components are not worth a command (and a zero would be a no-op round trip).
MIN_COMPONENT_M = 0.01


class BadInput(ValueError):
    """Stick input that is not three finite numbers within -1..1."""


@dataclass(frozen=True)
class Stick:
    forward: float
    right: float
    up: float

    @classmethod
    def parse(cls, data: object) -> Stick:
        if not isinstance(data, dict):
            raise BadInput("input must be an object with forward, right and up")
        values = []
        for name in ("forward", "right", "up"):
            value = data.get(name, 0.0)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise BadInput(f"{name} must be a number")
            if not math.isfinite(value) or abs(value) > 1.0:
                raise BadInput(f"{name} must be within -1..1")
            values.append(float(value))
        return cls(*values)

    @property
    def idle(self) -> bool:
        return self.forward == 0.0 and self.right == 0.0 and self.up == 0.0


def heading_of(orientation: list[float] | tuple[float, ...]) -> float:
    """Yaw in radians (clockwise from North) of a body-to-NED quaternion (qx, qy, qz, qw)."""
    x, y, z, w = orientation
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def commands_for(stick: Stick, heading_rad: float, step_m: float) -> list[tuple[str, float]]:
    """The control commands (name, value in metres) of one move.

    The horizontal deflection is capped at 1 so a diagonal is no faster than a straight
    line, then rotated from the heading frame into North/East.
    """
    forward, right = stick.forward, stick.right
    norm = math.hypot(forward, right)
    if norm > 1.0:
        forward, right = forward / norm, right / norm
    cos, sin = math.cos(heading_rad), math.sin(heading_rad)
    north = (forward * cos - right * sin) * step_m
    east = (forward * sin + right * cos) * step_m
    up = stick.up * step_m
    out = []
    for command, value in (("changeN", north), ("changeE", east), ("altitude", up)):
        if abs(value) >= MIN_COMPONENT_M:
            out.append((command, round(value, 3)))
    return out

"""The simulated wind: set at launch (`--wind SPEED,FROM`), changed in flight through the
MAVLink parameters SIM_WIND_SPD (m/s) and SIM_WIND_DIR (degrees the wind comes from, as
ArduPilot SITL names them) or a wind file (`--wind-file PATH`, the same `SPEED,FROM` text,
re-read when it changes) that tests and scripts rewrite.

The MAVLink personality reports it as its autopilot does (PX4 WIND_COV, ArduPilot WIND:
firmware/sim/mavlink_streams.py) and the vehicle drifts with it (firmware/sim/vehicle.py).
A dRonin board computes no wind estimate (its firmware defines WindVelocityActual but no
module writes it), so the UAVTalk personality only drifts.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

# The most wind the simulator takes: beyond hurricane force (32.7 m/s) is a typing error.
MAX_WIND_M_S = 60.0
# Wall seconds between looks at the wind file.
POLL_S = 0.2


class WindError(ValueError):
    """Wind text that is not SPEED,FROM with 0 <= SPEED <= MAX_WIND_M_S."""


def parse_wind(text: str) -> tuple[float, float]:
    """`"12,270"` → (12.0 m/s, 270.0 degrees it comes from)."""
    try:
        speed, from_deg = (float(part) for part in text.strip().split(","))
    except ValueError:
        raise WindError(f"wind must be SPEED,FROM (m/s, degrees), got {text.strip()!r}") from None
    if not (math.isfinite(speed) and math.isfinite(from_deg)) or not 0 <= speed <= MAX_WIND_M_S:
        raise WindError(f"wind speed must be from 0 to {MAX_WIND_M_S:g} m/s, got {speed:g}")
    return speed, from_deg % 360.0


def wind_ned(speed: float, from_deg: float) -> tuple[float, float, float]:
    """The air's velocity North-East-Down for a wind of `speed` from `from_deg`."""
    towards = math.radians(from_deg + 180.0)
    return speed * math.cos(towards), speed * math.sin(towards), 0.0


class WindFile:
    """A file holding `SPEED,FROM`, read again whenever it changes; a malformed one is
    ignored (the last good wind stays)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._stamp: tuple[int, int] | None = None
        self._next_look = -math.inf

    def changed(self, now: float) -> tuple[float, float] | None:
        """The new wind when the file changed since the last look, else None."""
        if now < self._next_look:
            return None
        self._next_look = now + POLL_S
        try:
            stat = os.stat(self.path)
        except OSError:
            return None
        stamp = (stat.st_mtime_ns, stat.st_size)
        if stamp == self._stamp:
            return None
        self._stamp = stamp
        try:
            return parse_wind(self.path.read_text())
        except (OSError, WindError):
            return None


def write_wind(path: Path, speed: float, from_deg: float) -> None:
    """Replace the wind file atomically (a reader never sees half of it)."""
    partial = path.with_suffix(path.suffix + ".partial")
    partial.write_text(f"{speed:g},{from_deg:g}\n")
    os.replace(partial, path)

"""How high a drone surely is along a sideways leg flown while a climb is under way (no Django).

The onboard agent sends a step's target as soon as the previous one is accepted: a
`navigate`, `changeN` or `changeE` sent while a take-off or a climb in place is still
under way (no `wait_for_flight` between them) is flown on a slant from the height the
drone is at, the flight controller flying both axes at once. The drone climbs at least
at its slowest (the climb rate stretched by the slack) while it flies at most at its
fastest (the leg's speed shrunk by the early factor), so at `d` metres along the leg it is
surely at least

    least(d) = min(the leg's target height, h0 + s·d),  s = slowest climb / fastest speed

above home, `h0` being the height it had surely reached when the leg began. The airspace
reserves its slanted legs with the same slope (airspace/corridors.py `slant_pieces`); the
terrain clearance holds the leg to it (terrain/guard.py, its climb-out rule).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol


class Paced(Protocol):
    """How fast a drone is assumed to fly (airspace/corridors.py Pace)."""

    @property
    def speed_m_s(self) -> float: ...
    @property
    def climb_m_s(self) -> float: ...
    @property
    def slack(self) -> float: ...
    @property
    def early(self) -> float: ...


def slowest_climb(pace: Paced) -> float:
    """Metres per second a drone surely climbs: its climb rate stretched by the slack."""
    return pace.climb_m_s / (1.0 + pace.slack)


def fastest_speed(speed: float, pace: Paced) -> float:
    """Metres per second a drone flying a leg at `speed` may go: shrunk by the early factor."""
    return speed / pace.early if pace.early > 0 else math.inf


def climb_slope(pace: Paced, speed: float | None = None) -> float:
    """Metres a drone surely climbs per metre it flies sideways (`speed`: the leg's own)."""
    return slowest_climb(pace) / fastest_speed(speed or pace.speed_m_s, pace)


@dataclass(frozen=True)
class Climb:
    """A climb under way as a sideways leg begins: the height above home the drone has
    surely reached (`start`, h0), the metres it surely climbs per metre flown, and where
    the climb began (`origin`, north and east metres from home; None: over home), whose
    ground the terrain's climb-out rule compares with."""

    start: float
    slope: float
    origin: tuple[float, float] | None = None

    def least(self, along: float, target: float) -> float:
        """The height above home the drone has surely reached `along` metres into the leg."""
        return min(target, self.start + self.slope * along)

    def reaches(self, height: float) -> float:
        """Metres into the leg by which the drone has surely climbed to `height`."""
        if height <= self.start:
            return 0.0
        return (height - self.start) / self.slope if self.slope > 0 else math.inf

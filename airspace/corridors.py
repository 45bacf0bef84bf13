"""The airspace a flight needs: its legs as corridors in space and time (no Django).

A flight is walked step by step, the way the drone's Navigation Processor flies it
(onboard/envelope.py `resolve`): a takeoff climbs in place, a `navigate` flies a straight
leg at the current height (plus its `altitude_delta`), `changeN`/`changeE` move
sideways, `altitude` climbs or descends in place, `land` descends to the ground, a
`sleep` hovers. Each leg becomes a corridor: the segment between its two ends with a
horizontal radius, an altitude band from its lowest to its highest height widened by the
vertical tolerance, and a time window.

Times: the flight's nominal clock runs at the leg's speed (a `navigate`'s own `speed`,
else the drone's cruise speed) and the climb rate. A drone may be faster (an autopilot
flying its own cruise speed) or slower (wind, acceleration, waypoints' tolerance
checks): a leg's window opens `buffer` seconds before its nominal start shrunk by `early`
(0.5: twice as fast) and closes `buffer` seconds after its nominal end stretched by
`slack` (0.5: half as slow again). A `sleep` before the drone has left the ground (a
staggered departure) is timed by the drone itself and is never shorter: it is not shrunk.
Heights are metres above the drone's home, as the envelope measures them.

A sideways move sent while a climb (or descent) in place is still under way — a `navigate`
straight after its `takeoff`, with no `wait_for_flight` between them — is flown on a slant:
the drone climbs and moves at once (onboard/navigation.py sends the new target at once;
the flight controller flies its horizontal and vertical axes together, each at its own
rate). A drone flying its steps as an autopilot mission (onboard/mavlink_mission.py)
finishes the take-off item first and flies level, as a paced leg does (its target waits
for the climb: onboard/mission.py PacedLeg). Its leg is reserved for both: from
where the climb began to the target, in pieces (`slant_pieces`), each with a band from the
lowest height the drone can be at along it — climbing at its slowest while moving at its
fastest, the pace's slack and early factors — up to its highest target. That slope is
terrain/climbout.py's `climb_slope`: the terrain clearance holds such a leg to the same
lowest heights.

A move sent while earlier moves are still under way (no `wait_for_flight` since them; a
`sleep` does not end them) may be flown from anywhere on them: a step-by-step drone turns
to its target from where it is, an autopilot mission flies through the earlier targets.
Besides its planned leg it is reserved as a fan (onboard/envelope.py `fan_origins`, the
rule stated once): legs from points at most 10 m apart along the unfinished moves' hull to
its target, each there from the time the move may be sent until the later of the planned
leg's end and the time flying straight from the farthest origin takes, at any height
between the lowest and highest of the unfinished moves' ends and the target. Of moves
sent together (no wait_for_flight nor sleep between them) only the last one's fan is
reserved: it covers the others' (`_kept_fans`). Cutting the corner the drone may reach
the target sooner than through the earlier targets: the later legs' windows open from
that soonest time (`_Where.soonest`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

from onboard import envelope as env
from terrain.climbout import climb_slope, slowest_climb

EARTH_RADIUS = 6_378_137.0  # WGS-84 equatorial radius, as onboard/envelope.py uses
# Below this height a drone is on the ground: it takes no airspace.
GROUND_M = 0.5


@dataclass(frozen=True)
class Pace:
    """How fast a drone is assumed to fly, and how its legs' windows are widened."""

    speed_m_s: float = 5.0
    climb_m_s: float = 2.0
    slack: float = 0.5
    early: float = 0.5
    buffer_s: float = 30.0
    hold_s: float = 300.0  # how long the drone is assumed to hover after its last step
    radius_m: float = 2.0
    vertical_m: float = 2.0
    # A slanted leg's pieces: the lowest height along it rises by at most this within one
    # piece (the vertical minimum, so a piece's band is never a minimum too low).
    step_m: float = 10.0


@dataclass(frozen=True)
class Leg:
    """One corridor: from (lat0, lon0) to (lat1, lon1), heights low..high above home,
    reserved from t0 to t1 (seconds since the epoch); `step` is the position of the step
    it flies in the steps walked (None: the hover after the last one). It is not stored."""

    lat0: float
    lon0: float
    lat1: float
    lon1: float
    low: float
    high: float
    t0: float
    t1: float
    step: int | None = field(default=None, compare=False)

    def to_list(self) -> list[float]:
        return [self.lat0, self.lon0, self.lat1, self.lon1, self.low, self.high, self.t0, self.t1]

    @classmethod
    def from_list(cls, values: Sequence[float]) -> Leg:
        return cls(*(float(v) for v in values[:8]))


@dataclass
class _Where:
    lat: float
    lon: float
    height: float
    seconds: float  # nominal time since the flight began
    waited: float = 0.0  # of which spent waiting on the ground before leaving it
    # The soonest nominal time the drone can be here: earlier than `seconds` after a move
    # that may cut the corner of the moves before it (the fan below). None: `seconds`.
    soonest: float | None = None

    @property
    def earliest(self) -> float:
        return self.seconds if self.soonest is None else min(self.seconds, self.soonest)


def offset(lat: float, lon: float, north: float, east: float) -> tuple[float, float]:
    """The point `north`, `east` metres from (lat, lon), on the local flat earth."""
    dlat = math.degrees(north / EARTH_RADIUS)
    dlon = math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat))))
    return lat + dlat, lon + dlon


def ground_distance(lat0: float, lon0: float, lat1: float, lon1: float) -> float:
    """Metres between two points on the local flat earth (as onboard/envelope.py)."""
    north = math.radians(lat1 - lat0) * EARTH_RADIUS
    east = math.radians(lon1 - lon0) * EARTH_RADIUS * math.cos(math.radians((lat0 + lat1) / 2))
    return math.hypot(north, east)


def _target(step: Mapping, here: _Where) -> tuple[float, float, float, float | None] | None:
    """Where a step sends the drone (lat, lon, height, its leg's own speed), or None for
    a step that does not move it."""
    command, params = step.get("command"), step.get("params") or {}
    if command == "takeoff":
        return here.lat, here.lon, float(params.get("altitude", 10.0)), None
    if command == "land":
        return here.lat, here.lon, 0.0, None
    if command == "altitude":
        return here.lat, here.lon, here.height + float(params["value"]), None
    if command in ("changeN", "changeE"):
        north = float(params["value"]) if command == "changeN" else 0.0
        east = float(params["value"]) if command == "changeE" else 0.0
        return (*offset(here.lat, here.lon, north, east), here.height, None)
    if command == "navigate":
        height = here.height + float(params.get("altitude_delta") or 0.0)
        speed = params.get("speed")
        return float(params["lat"]), float(params["lon"]), height, speed and float(speed)
    return None


SIDEWAYS = ("navigate", "changeN", "changeE")


@dataclass
class _Rise:
    """A climb or descent in place still under way: from `start` metres, sent to each of
    `heights` in turn, sent at `sent` seconds of the flight's clock (moved on by sleeps:
    the drone goes on climbing through them). `least`: metres it has surely come from
    `start` towards them (climbing at its slowest)."""

    start: float
    heights: list[float]
    sent: float
    least: float = 0.0

    @property
    def direction(self) -> float:
        return 1.0 if self.heights[0] >= self.start else -1.0

    def slept(self, seconds: float, pace: Pace) -> None:
        reach = max(0.0, self.direction * (self.heights[-1] - self.start))
        self.least = min(reach, self.least + seconds * slowest_climb(pace))
        self.sent += seconds

    def sent_to(self, height: float) -> None:
        self.heights.append(height)
        self.least = min(self.least, max(0.0, self.direction * (height - self.start)))


@dataclass(frozen=True)
class _Move:
    """One step's move: from `a` to `b`, its position among the steps, its leg's own speed
    and, for a sideways move flown on a slant, the climb under way when it was sent."""

    a: _Where
    b: _Where
    step: int
    speed: float | None = None
    rise: _Rise | None = None
    # Sent while earlier moves were under way: those moves (its fan starts on their
    # hull), when it may be sent, and which moves were sent together with it (no
    # wait_for_flight nor sleep between them).
    unfinished: _Unfinished | None = None
    sent: float = 0.0
    burst: int = 0


def _window(
    start_s: float, end_s: float, waited: float, pace: Pace, began: float
) -> tuple[float, float]:
    t0 = began + waited + (start_s - waited) * pace.early - pace.buffer_s
    t1 = began + end_s * (1.0 + pace.slack) + pace.buffer_s
    return t0, t1


def _leg(start: _Where, end: _Where, pace: Pace, began: float, step: int | None) -> Leg:
    t0, t1 = _window(start.earliest, end.seconds, start.waited, pace, began)
    low = max(0.0, min(start.height, end.height) - pace.vertical_m)
    high = max(start.height, end.height) + pace.vertical_m
    return Leg(start.lat, start.lon, end.lat, end.lon, low, high, t0, t1, step)


@dataclass(frozen=True)
class _Unfinished:
    """The moves under way since the last wait_for_flight: the corners of the hull of
    where they began and of their targets, in metres about `base` (lat, lon), and the
    lowest and highest of those heights. Only the corners are kept: the hull of them and a
    new target is the hull of every point and it, so a long burst costs its hull's size."""

    base: tuple[float, float]
    corners: tuple[env.NED, ...]
    low: float
    high: float

    @classmethod
    def at(cls, where: _Where) -> _Unfinished:
        return cls((where.lat, where.lon), ((0.0, 0.0, -where.height),), where.height, where.height)

    def local(self, where: _Where) -> env.NED:
        north, east = env.latlon_to_ne(where.lat, where.lon, self.base)
        return north, east, -where.height

    def sent_to(self, where: _Where) -> _Unfinished:
        corners = tuple(env.hull_corners([*self.corners, self.local(where)]))
        return _Unfinished(
            self.base, corners, min(self.low, where.height), max(self.high, where.height)
        )

    def fan(self, start: _Where, target: _Where) -> list[_Where]:
        """onboard/envelope.py `fan_origins` for a move from `start` (its previous target)
        to `target`: where else it may be flown from."""
        goal = self.local(target)
        return [
            _Where(*env.ned_to_latlon(north, east, self.base), -down, 0.0)
            for north, east, down in env.fan_origins([*self.corners, self.local(start)])
            if math.dist((north, east), goal[:2]) >= env.MIN_LEG
        ]

    def farthest(self, target: _Where) -> float:
        """Metres from the hull's farthest corner to `target` (no origin is farther)."""
        goal = self.local(target)
        return max(math.dist(corner[:2], goal[:2]) for corner in self.corners)


def _moves(steps: Sequence[Mapping], start: _Where, pace: Pace) -> Iterator[_Move]:
    """Each step that moves the drone or makes it hover, in flying order. A climb or
    descent in place stays under way until a `wait_for_flight` or the next move; a
    sideways move sent meanwhile carries it (`rise`). Moves stay under way until a
    `wait_for_flight`; one sent meanwhile carries its fan (`fan`)."""
    here = start
    rise: _Rise | None = None
    unfinished = _Unfinished.at(start)
    burst = 0
    sent = start.seconds  # the soonest the next step can be sent: at once, unless waited
    for position, step in enumerate(steps):
        command = step.get("command")
        if command == "wait_for_flight":
            rise = None
            unfinished, sent, burst = _Unfinished.at(here), max(sent, here.earliest), burst + 1
            continue
        if command == "sleep":
            value = float((step.get("params") or {}).get("value", 0.0))
            before_leaving = here.height < GROUND_M and here.seconds == here.waited
            waited = here.waited + value if before_leaving else here.waited
            end = _Where(
                here.lat, here.lon, here.height, here.seconds + value, waited, here.earliest + value
            )
            if rise is not None:
                rise.slept(value, pace)
            sent, burst = sent + value, burst + 1
            yield _Move(here, end, position)
            here = end
            continue
        target = _target(step, here)
        if target is None:
            continue
        lat, lon, height, speed = target
        across = ground_distance(here.lat, here.lon, lat, lon)
        seconds = across / (speed or pace.speed_m_s) + abs(height - here.height) / pace.climb_m_s
        end = _Where(lat, lon, height, here.seconds + seconds, here.waited, here.earliest + seconds)
        slanted = rise if command in SIDEWAYS and across > 0 else None
        under_way = None
        if command in (*SIDEWAYS, "altitude") and len(unfinished.corners) > 1:
            under_way = unfinished
            # Cutting the corner, it may be there sooner than through the earlier targets.
            still = env.hull_distance(unfinished.corners, unfinished.local(end))
            end.soonest = min(end.earliest, sent + still / (speed or pace.speed_m_s))
        yield _Move(here, end, position, speed, slanted, under_way, sent, burst)
        unfinished = unfinished.sent_to(end)
        # A move in place (a sideways one to where the drone is too) leaves the climb under
        # way, towards its new height; a sideways leg flies it out.
        if slanted is not None or across > 0:
            rise = None
        elif rise is not None:
            rise.sent_to(height)
        elif height != here.height:
            rise = _Rise(here.height, [height], here.seconds)
        here = end


def _fan_end(move: _Move, pace: Pace) -> float:
    """When its fan's flights may end (nominal): the later of the planned leg's end and
    the time flying straight from the farthest origin takes after the move was sent."""
    u = move.unfinished
    assert u is not None
    b, speed = move.b, move.speed or pace.speed_m_s
    climb = max(abs(b.height - u.low), abs(b.height - u.high)) / pace.climb_m_s
    return max(b.seconds, move.sent + u.farthest(b) / speed + climb)


def _fan_legs(move: _Move, pace: Pace, began: float, until: float) -> list[Leg]:
    """A move's fan legs (onboard/envelope.py `fan_origins`): each from one of its origins
    to its target, there from the time it may be sent until `until` (nominal), at any
    height the unfinished moves and the target span."""
    u, b = move.unfinished, move.b
    assert u is not None
    low = max(0.0, min(u.low, b.height) - pace.vertical_m)
    high = max(u.high, b.height) + pace.vertical_m
    t0, t1 = _window(move.sent, until, move.a.waited, pace, began)
    return [
        Leg(origin.lat, origin.lon, b.lat, b.lon, low, high, t0, t1, move.step)
        for origin in u.fan(move.a, b)
    ]


def _kept_fans(moves: Sequence[_Move], pace: Pace) -> dict[int, float]:
    """Which moves' fans are reserved (by position in `moves`), each until when.

    Moves sent together (one burst) are all under way at once: the last one's fan covers
    the region of each earlier one's (the hull it starts from holds their origins and
    targets), its band theirs (the heights of more ends) and its window opens as theirs
    (the same sending time). Only it is reserved, until the latest end of theirs: the
    flight's legs stay about one fan per burst, not one per move. A conflict met there
    names that last move's step."""
    last: dict[int, int] = {}
    until: dict[int, float] = {}
    for position, move in enumerate(moves):
        if move.unfinished is not None:
            last[move.burst] = position
            until[move.burst] = max(until.get(move.burst, 0.0), _fan_end(move, pace))
    return {position: until[burst] for burst, position in last.items()}


def slant_pieces(move: _Move, pace: Pace) -> list[tuple[float, float, float]]:
    """A sideways leg flown while a climb is under way, as (from, to, least) pieces: the
    shares of the leg each piece covers and the metres from the climb's start the drone
    has surely come by the piece's start. The drone comes at least as far as its slowest
    climb over the time its fastest flight takes to get there; pieces end where that
    passes a multiple of `pace.step_m` and where it reaches the target's height."""
    rise, a, b = move.rise, move.a, move.b
    assert rise is not None
    need = rise.direction * (b.height - rise.start)
    across = ground_distance(a.lat, a.lon, b.lat, b.lon)
    # Metres of climb per metre flown, at the slowest climb and the fastest flight.
    slope = climb_slope(pace, move.speed)
    cuts = {0.0, 1.0}
    if slope > 0 and pace.step_m > 0:
        k = math.floor(rise.least / pace.step_m) + 1
        heights = [j * pace.step_m for j in range(k, math.ceil(need / pace.step_m))]
        for height in [*heights, need]:
            share = (height - rise.least) / slope / across
            if 0.0 < share < 1.0:
                cuts.add(share)
    shares = sorted(cuts)

    def least_at(share: float) -> float:
        return min(need, rise.least + slope * share * across)

    return [(s0, s1, least_at(s0)) for s0, s1 in zip(shares, shares[1:], strict=False)]


def _slanted_legs(move: _Move, pace: Pace, began: float) -> list[Leg]:
    """The legs of a sideways move flown while a climb is under way (see the module's
    docstring): one per piece, or one over every height it was sent to when its heights
    do not all lie on one side of where the climb began."""
    rise, a, b = move.rise, move.a, move.b
    assert rise is not None
    heights = [*rise.heights, b.height]
    d = rise.direction
    if min(d * (h - rise.start) for h in heights) < 0 or b.height == rise.start:
        every = [rise.start, *heights]
        t0, t1 = _window(rise.sent, b.seconds, a.waited, pace, began)
        low = max(0.0, min(every) - pace.vertical_m)
        high = max(every) + pace.vertical_m
        return [Leg(a.lat, a.lon, b.lat, b.lon, low, high, t0, t1, move.step)]
    far = max(d * (h - rise.start) for h in heights)
    speed = move.speed or pace.speed_m_s
    across = ground_distance(a.lat, a.lon, b.lat, b.lon)
    legs = []
    for s0, s1, least in slant_pieces(move, pace):
        lat0, lon0 = a.lat + s0 * (b.lat - a.lat), a.lon + s0 * (b.lon - a.lon)
        lat1, lon1 = a.lat + s1 * (b.lat - a.lat), a.lon + s1 * (b.lon - a.lon)
        # Flown on the slant it is there from the time it was sent; climbing first, no
        # later than the level leg would be.
        t0, t1 = _window(
            rise.sent + s0 * across / speed,
            a.seconds + s1 * (b.seconds - a.seconds),
            a.waited,
            pace,
            began,
        )
        ends = sorted((rise.start + d * least, rise.start + d * far))
        low, high = max(0.0, ends[0] - pace.vertical_m), ends[1] + pace.vertical_m
        legs.append(Leg(lat0, lon0, lat1, lon1, low, high, t0, t1, move.step))
    return legs


def flight_legs(
    steps: Sequence[Mapping],
    position: tuple[float, float, float],
    began: float,
    pace: Pace,
) -> tuple[list[Leg], float]:
    """The corridors of a flight from `position` (lat, lon, height above home) starting
    at `began`, and the latest time by which the drone should be airborne (its first
    corridor's nominal start, widened like a window's end; `began` when it flies already).

    Legs on the ground take no airspace; after its last step a drone still in the air
    hovers where it is for `pace.hold_s`. A sideways move sent while a climb is under way
    is reserved on its slant, in pieces (`slant_pieces`).
    """
    start = _Where(position[0], position[1], max(0.0, position[2]), 0.0)
    legs: list[Leg] = []
    airborne_by: float | None = began if start.height >= GROUND_M else None
    last = start
    moves = list(_moves(steps, start, pace))
    fans = _kept_fans(moves, pace)
    for position, move in enumerate(moves):
        a, b = move.a, move.b
        last = b
        if max(a.height, b.height) < GROUND_M:
            continue
        if airborne_by is None:
            airborne_by = began + a.seconds * (1.0 + pace.slack) + pace.buffer_s
        if move.rise is not None:
            legs.extend(_slanted_legs(move, pace, began))
        else:
            legs.append(_leg(a, b, pace, began, move.step))
        if position in fans:
            legs.extend(_fan_legs(move, pace, began, fans[position]))
    if last.height >= GROUND_M:
        hover = _Where(last.lat, last.lon, last.height, last.seconds + pace.hold_s)
        legs.append(_leg(last, hover, pace, began, None))
    return legs, began if airborne_by is None else airborne_by


def hold_legs(position: tuple[float, float, float], began: float, pace: Pace) -> list[Leg]:
    """A drone in the air with no plan known: the column under it, from now for
    `pace.hold_s` (it hovers, or comes down where it is)."""
    lat, lon, height = position
    if height < GROUND_M:
        return []
    return [Leg(lat, lon, lat, lon, 0.0, height + pace.vertical_m, began, began + pace.hold_s)]


def with_takeoff_altitude(steps: Sequence[Mapping], altitude: float) -> list[dict]:
    """The steps with every takeoff climbing to `altitude` (a layer)."""
    out = []
    for step in steps:
        step = {**step, "params": dict(step.get("params") or {})}
        if step.get("command") == "takeoff":
            step["params"]["altitude"] = altitude
        out.append(step)
    return out


def takeoff_altitude(steps: Sequence[Mapping]) -> float | None:
    """The height the first takeoff climbs to, or None when the steps take off nowhere."""
    for step in steps:
        if step.get("command") == "takeoff":
            return float((step.get("params") or {}).get("altitude", 10.0))
    return None

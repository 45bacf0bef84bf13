"""The flight envelope: limits and a geofence, and the one check both the ground and the drone run.

An envelope holds a maximum height and horizontal distance from home, a minimum height for
horizontal moves once airborne, a battery reserve below which only landing and returning
home are accepted, and a geofence in QGroundControl's `.plan` `geoFence` shape (inclusion and
exclusion polygons and circles), so a QGroundControl fence imports and exports as is.

Positions are North-East-Down metres from home, linearised about home as the Navigation
Processor does (onboard/navigation.py); the fence is in WGS84 degrees and is tested in the
same local frame. Standard library only: the ground imports this module too.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import threading
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

EARTH_RADIUS = 6_378_137.0
DEFAULT_MAX_HEIGHT = 120.0
DEFAULT_MAX_DISTANCE = 1000.0
DEFAULT_MIN_MOVE_HEIGHT = 2.0
DEFAULT_BATTERY_RESERVE = 30.0
# A "return" under the battery reserve is a move ending this close to home (horizontally).
RETURN_RADIUS = 5.0
MAX_FENCE_VERTICES = 1000
# The least area a polygon encloses: a smaller one is a line or a point, not a place.
MIN_POLYGON_AREA_M2 = 0.01
MAX_FENCES = 100
QGC_FENCE_VERSION = 2
QGC_SHAPE_VERSION = 1
# Commands that move the drone sideways, so the minimum move height applies to them.
HORIZONTAL_COMMANDS = ("changeN", "changeE", "navigate")
NED = tuple[float, float, float]
LatLon = tuple[float, float]


class EnvelopeError(ValueError):
    """A malformed envelope or fence; `field` names the offending field (dotted path)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


@dataclass(frozen=True)
class Polygon:
    inclusion: bool
    points: tuple[LatLon, ...]


@dataclass(frozen=True)
class Circle:
    inclusion: bool
    center: LatLon
    radius: float


@dataclass(frozen=True)
class Envelope:
    max_height: float = DEFAULT_MAX_HEIGHT
    max_distance: float = DEFAULT_MAX_DISTANCE
    min_move_height: float = DEFAULT_MIN_MOVE_HEIGHT
    battery_reserve: float = DEFAULT_BATTERY_RESERVE
    polygons: tuple[Polygon, ...] = field(default_factory=tuple)
    circles: tuple[Circle, ...] = field(default_factory=tuple)

    def restricted(
        self, max_height: float | None = None, max_distance: float | None = None
    ) -> Envelope:
        """This envelope with a drone's own limits, which may only lower the organisation's."""
        return replace(
            self,
            max_height=min(self.max_height, max_height if max_height is not None else math.inf),
            max_distance=min(
                self.max_distance, max_distance if max_distance is not None else math.inf
            ),
        )

    @property
    def has_inclusion(self) -> bool:
        return any(p.inclusion for p in self.polygons) or any(c.inclusion for c in self.circles)

    def to_dict(self) -> dict:
        """The wire and storage form: the limits and a QGroundControl `geoFence` object."""
        return {
            "max_height": self.max_height,
            "max_distance": self.max_distance,
            "min_move_height": self.min_move_height,
            "battery_reserve": self.battery_reserve,
            "geoFence": geofence_dict(self),
        }


@dataclass(frozen=True)
class Move:
    """Where a command sends the drone: kind ("takeoff", "land", "goto") and NED from home."""

    kind: str
    ned: NED
    horizontal: bool = False


@dataclass(frozen=True)
class Violation:
    """A refused move: which limit (`max_height`, `geofence`, ...) and a sentence naming it.

    `leg` is the straight leg (from, to) as (lat, lon) when the leg, not its end, is refused.
    """

    limit: str
    message: str
    leg: tuple[LatLon, LatLon] | None = None


# -- parsing ------------------------------------------------------------------------------


def _number(value: Any, name: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise EnvelopeError(name, f"must be a number, got {value!r}")
    result = float(value)
    if not math.isfinite(result) or not lo <= result <= hi:
        raise EnvelopeError(name, f"must be between {lo:g} and {hi:g}, got {value!r}")
    return result


def parse_latlon(value: Any, name: str) -> LatLon:
    if not isinstance(value, list | tuple) or len(value) < 2:
        raise EnvelopeError(name, "must be [latitude, longitude]")
    lat = _number(value[0], f"{name}[0]", -89.0, 89.0)
    return lat, _number(value[1], f"{name}[1]", -180.0, 180.0)


def _list(value: Any, name: str, limit: int) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise EnvelopeError(name, "must be a list")
    if len(value) > limit:
        raise EnvelopeError(name, f"must have at most {limit} entries")
    return value


def _inclusion(obj: Mapping, name: str) -> bool:
    value = obj.get("inclusion", True)
    if not isinstance(value, bool):
        raise EnvelopeError(f"{name}.inclusion", "must be true or false")
    return value


def _polygon(obj: Any, name: str) -> Polygon:
    if not isinstance(obj, dict):
        raise EnvelopeError(name, "must be an object")
    raw = _list(obj.get("polygon"), f"{name}.polygon", MAX_FENCE_VERTICES)
    points = tuple(parse_latlon(p, f"{name}.polygon[{i}]") for i, p in enumerate(raw))
    if len(points) >= 2 and points[0] == points[-1]:
        points = points[:-1]  # a closed ring repeats its first vertex
    if len(set(points)) < 3:
        raise EnvelopeError(f"{name}.polygon", "needs at least 3 distinct points")
    local = _to_local(points, points[0])
    if _self_intersects(local):
        raise EnvelopeError(f"{name}.polygon", "must not intersect itself")
    if abs(_twice_area(local)) < MIN_POLYGON_AREA_M2 * 2:
        # A ring drawn there and back (a wall in a KML export) has points but no inside.
        raise EnvelopeError(f"{name}.polygon", "encloses no area: its points lie on one line")
    return Polygon(_inclusion(obj, name), points)


def _twice_area(ring: list[tuple[float, float]]) -> float:
    """Twice the signed area of a ring (the shoelace formula), in square metres."""
    return sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(ring, ring[1:] + ring[:1], strict=True))


def _circle(obj: Any, name: str) -> Circle:
    if not isinstance(obj, dict) or not isinstance(obj.get("circle"), dict):
        raise EnvelopeError(f"{name}.circle", "must be an object {center, radius}")
    center = parse_latlon(obj["circle"].get("center"), f"{name}.circle.center")
    radius = _number(obj["circle"].get("radius"), f"{name}.circle.radius", 0.1, 1e6)
    return Circle(_inclusion(obj, name), center, radius)


def parse_geofence(
    obj: Any, name: str = "geoFence"
) -> tuple[tuple[Polygon, ...], tuple[Circle, ...]]:
    """QGroundControl's `geoFence` object → (polygons, circles), or EnvelopeError."""
    if obj is None:
        return (), ()
    if not isinstance(obj, dict):
        raise EnvelopeError(name, "must be an object")
    polygons = _list(obj.get("polygons"), f"{name}.polygons", MAX_FENCES)
    circles = _list(obj.get("circles"), f"{name}.circles", MAX_FENCES)
    return (
        tuple(_polygon(p, f"{name}.polygons[{i}]") for i, p in enumerate(polygons)),
        tuple(_circle(c, f"{name}.circles[{i}]") for i, c in enumerate(circles)),
    )


def parse_envelope(obj: Any, home: Sequence[float] | None = None) -> Envelope:
    """A JSON envelope (missing limits take the defaults) → Envelope, or EnvelopeError.

    With `home` given, the inclusion fences must contain it: a fence that excludes the
    launch point would refuse every move.
    """
    if not isinstance(obj, dict):
        raise EnvelopeError("envelope", "must be a JSON object")
    limits = {
        "max_height": (DEFAULT_MAX_HEIGHT, 1.0, 10_000.0),
        "max_distance": (DEFAULT_MAX_DISTANCE, 1.0, 1_000_000.0),
        "min_move_height": (DEFAULT_MIN_MOVE_HEIGHT, 0.0, 10_000.0),
        "battery_reserve": (DEFAULT_BATTERY_RESERVE, 0.0, 100.0),
    }
    values = {
        key: default if obj.get(key) is None else _number(obj[key], key, lo, hi)
        for key, (default, lo, hi) in limits.items()
    }
    if values["min_move_height"] > values["max_height"]:
        raise EnvelopeError("min_move_height", "must not exceed max_height")
    polygons, circles = parse_geofence(obj.get("geoFence"))
    envelope = Envelope(**values, polygons=polygons, circles=circles)
    if home is not None and envelope.has_inclusion and fence_breach(envelope, _ll(home)):
        raise EnvelopeError("geoFence", "the inclusion fence must contain home")
    return envelope


def _ll(point: Sequence[float]) -> LatLon:
    return float(point[0]), float(point[1])


def geofence_dict(envelope: Envelope) -> dict:
    """The fence as QGroundControl writes it in a `.plan` file."""
    return {
        "version": QGC_FENCE_VERSION,
        "polygons": [
            {
                "inclusion": p.inclusion,
                "polygon": [list(point) for point in p.points],
                "version": QGC_SHAPE_VERSION,
            }
            for p in envelope.polygons
        ],
        "circles": [
            {
                "inclusion": c.inclusion,
                "circle": {"center": list(c.center), "radius": c.radius},
                "version": QGC_SHAPE_VERSION,
            }
            for c in envelope.circles
        ],
    }


# -- geometry -----------------------------------------------------------------------------


def ned_to_latlon(north: float, east: float, home: Sequence[float]) -> LatLon:
    lat = home[0] + math.degrees(north / EARTH_RADIUS)
    lon = home[1] + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(home[0]))))
    return lat, lon


def latlon_to_ne(lat: float, lon: float, origin: Sequence[float]) -> tuple[float, float]:
    north = EARTH_RADIUS * math.radians(lat - origin[0])
    dlon = (lon - origin[1] + 180.0) % 360.0 - 180.0
    return north, EARTH_RADIUS * math.cos(math.radians(origin[0])) * math.radians(dlon)


def _to_local(points: Iterable[LatLon], origin: Sequence[float]) -> list[tuple[float, float]]:
    return [latlon_to_ne(lat, lon, origin) for lat, lon in points]


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_cross(p1, p2, q1, q2) -> bool:  # type: ignore[no-untyped-def]
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    return (d1 > 0) != (d2 > 0) and (d3 > 0) != (d4 > 0) and 0 not in (d1, d2, d3, d4)


def _self_intersects(ring: list[tuple[float, float]]) -> bool:
    """Any two non-adjacent edges crossing (touching at a shared vertex is not crossing).

    Edges are swept in order of their lowest first coordinate: only pairs whose extents
    overlap along it are compared (others cannot cross), so a ring of n vertices costs
    about n log n rather than n² comparisons.
    """
    count = len(ring)
    edges = [(ring[i], ring[(i + 1) % count]) for i in range(count)]
    order = sorted(range(count), key=lambda i: min(edges[i][0][0], edges[i][1][0]))
    for position, i in enumerate(order):
        top = max(edges[i][0][0], edges[i][1][0])
        for j in order[position + 1 :]:
            if min(edges[j][0][0], edges[j][1][0]) > top:
                break
            if abs(i - j) in (1, count - 1):
                continue  # neighbours share a vertex
            if _segments_cross(*edges[i], *edges[j]):
                return True
    return False


def _inside_polygon(point: LatLon, polygon: Polygon) -> bool:
    """Ray casting in the local frame about the point itself."""
    ring = _to_local(polygon.points, point)
    inside = False
    for (n1, e1), (n2, e2) in zip(ring, ring[1:] + ring[:1], strict=True):
        if (e1 > 0) != (e2 > 0) and 0 < n1 + (n2 - n1) * (0 - e1) / (e2 - e1):
            inside = not inside
    return inside


def _inside_circle(point: LatLon, circle: Circle) -> bool:
    north, east = latlon_to_ne(*point, circle.center)
    return math.hypot(north, east) <= circle.radius


def fence_breach(envelope: Envelope, point: LatLon) -> str | None:
    """Why `point` breaks the fence (outside every inclusion, or inside an exclusion), or None."""
    inclusions = [p for p in envelope.polygons if p.inclusion]
    inclusion_circles = [c for c in envelope.circles if c.inclusion]
    if inclusions or inclusion_circles:
        inside = any(_inside_polygon(point, p) for p in inclusions) or any(
            _inside_circle(point, c) for c in inclusion_circles
        )
        if not inside:
            return "outside the geofence's inclusion zones"
    for index, polygon in enumerate(envelope.polygons):
        if not polygon.inclusion and _inside_polygon(point, polygon):
            return f"inside the geofence's exclusion polygon {index}"
    for index, circle in enumerate(envelope.circles):
        if not circle.inclusion and _inside_circle(point, circle):
            return f"inside the geofence's exclusion circle {index}"
    return None


# -- legs ---------------------------------------------------------------------------------
# A leg is the straight line the drone flies between two targets, in the local frame
# about home. The fence's borders cut it into pieces; each piece is wholly inside or
# outside a zone, so testing its midpoint with the point rules decides it.

NE = tuple[float, float]
# Legs shorter than this (horizontally) are vertical: the point check covers them.
MIN_LEG = 1e-3


def _edge_crossing(a: NE, b: NE, p: NE, q: NE) -> float | None:
    """Where along a→b (0..1) it meets the edge p→q, or None."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    ex, ey = q[0] - p[0], q[1] - p[1]
    denominator = dx * ey - dy * ex
    if denominator == 0:
        return None
    t = ((p[0] - a[0]) * ey - (p[1] - a[1]) * ex) / denominator
    u = ((p[0] - a[0]) * dy - (p[1] - a[1]) * dx) / denominator
    return t if 0 < t < 1 and 0 <= u <= 1 else None


def _circle_crossings(a: NE, b: NE, center: NE, radius: float) -> list[float]:
    dx, dy = b[0] - a[0], b[1] - a[1]
    fx, fy = a[0] - center[0], a[1] - center[1]
    qa, qb, qc = dx * dx + dy * dy, 2 * (fx * dx + fy * dy), fx * fx + fy * fy - radius * radius
    discriminant = qb * qb - 4 * qa * qc
    if discriminant <= 0:
        return []
    root = math.sqrt(discriminant)
    return [t for t in ((-qb - root) / (2 * qa), (-qb + root) / (2 * qa)) if 0 < t < 1]


@dataclass(frozen=True)
class _LocalZone:
    """A zone in the local frame about home: its ring (polygon) or centre and radius
    (circle), and its bounding box (min north, min east, max north, max east)."""

    ring: tuple[NE, ...]
    center: NE
    radius: float
    box: tuple[float, float, float, float]


@functools.lru_cache(maxsize=1024)
def _local_zone(zone: Polygon | Circle, home: LatLon) -> _LocalZone:
    if isinstance(zone, Circle):
        c = latlon_to_ne(*zone.center, home)
        r = zone.radius
        return _LocalZone((), c, r, (c[0] - r, c[1] - r, c[0] + r, c[1] + r))
    ring = tuple(_to_local(zone.points, home))
    norths, easts = [p[0] for p in ring], [p[1] for p in ring]
    return _LocalZone(ring, (0.0, 0.0), 0.0, (min(norths), min(easts), max(norths), max(easts)))


def _near(zone: _LocalZone, a: NE, b: NE) -> bool:
    """The leg's bounding box meets the zone's: else no part of the leg is in the zone."""
    n0, e0, n1, e1 = zone.box
    return not (
        max(a[0], b[0]) < n0 or min(a[0], b[0]) > n1 or max(a[1], b[1]) < e0 or min(a[1], b[1]) > e1
    )


def _borders(zone: _LocalZone, a: NE, b: NE) -> list[float]:
    if not zone.ring:
        return _circle_crossings(a, b, zone.center, zone.radius)
    ring = list(zone.ring)
    found = (_edge_crossing(a, b, p, q) for p, q in zip(ring, ring[1:] + ring[:1], strict=True))
    return [t for t in found if t is not None]


def _inside(zone: _LocalZone, point: NE) -> bool:
    """The point rules (_inside_circle, _inside_polygon) in the local frame about home."""
    n, e = point
    if not zone.ring:
        return math.hypot(n - zone.center[0], e - zone.center[1]) <= zone.radius
    inside = False
    ring = zone.ring
    for (n1, e1), (n2, e2) in zip(ring, ring[1:] + ring[:1], strict=True):
        if (e1 > e) != (e2 > e) and n < n1 + (n2 - n1) * (e - e1) / (e2 - e1):
            inside = not inside
    return inside


def _pieces(zones: Sequence[_LocalZone], a: NE, b: NE) -> list[NE]:
    """The midpoint of every piece the zones' borders cut the leg a→b into; none when no
    border crosses it (the whole leg is then on the same side as its start)."""
    crossings = {t for zone in zones for t in _borders(zone, a, b)}
    if not crossings:
        return []
    cuts = sorted({0.0, 1.0, *crossings})
    middles = ((t0 + t1) / 2 for t0, t1 in zip(cuts, cuts[1:], strict=False))
    return [(a[0] + m * (b[0] - a[0]), a[1] + m * (b[1] - a[1])) for m in middles]


def leg_breach(envelope: Envelope, home: Sequence[float], start: NED, end: NED) -> str | None:
    """Why the straight leg start→end leaves the inclusion zones or crosses an exclusion
    zone, or None.

    A zone the leg starts in the wrong side of is not held against it: a drone put outside
    (a fence drawn around it, wind) must be able to fly back; its end is checked anyway.
    """
    a, b = (start[0], start[1]), (end[0], end[1])
    if math.hypot(b[0] - a[0], b[1] - a[1]) < MIN_LEG:
        return None
    origin = _ll(home)
    inclusions = [
        local
        for zone in (*envelope.polygons, *envelope.circles)
        if zone.inclusion and _near(local := _local_zone(zone, origin), a, b)
    ]
    if any(_inside(zone, a) for zone in inclusions):
        for point in _pieces(inclusions, a, b):
            if not any(_inside(zone, point) for zone in inclusions):
                return "leaves the geofence's inclusion zones"
    for kind, group in (("polygon", envelope.polygons), ("circle", envelope.circles)):
        for index, zone in enumerate(group):
            local = _local_zone(zone, origin)
            if zone.inclusion or not _near(local, a, b) or _inside(local, a):
                continue
            if any(_inside(local, point) for point in _pieces([local], a, b)):
                return f"crosses the geofence's exclusion {kind} {index}"
    return None


def local_fence_breach(envelope: Envelope, home: Sequence[float], point: NE) -> str | None:
    """fence_breach for a point given in metres from home: the zones are taken in the
    local frame about home once (cached), as the legs are."""
    origin = _ll(home)
    zones = [(z, _local_zone(z, origin)) for z in (*envelope.polygons, *envelope.circles)]
    inclusions = [local for zone, local in zones if zone.inclusion]
    if inclusions and not any(_near(z, point, point) and _inside(z, point) for z in inclusions):
        return "outside the geofence's inclusion zones"
    for kind, group in (("polygon", envelope.polygons), ("circle", envelope.circles)):
        for index, zone in enumerate(group):
            local = _local_zone(zone, origin)
            if not zone.inclusion and _near(local, point, point) and _inside(local, point):
                return f"inside the geofence's exclusion {kind} {index}"
    return None


def _leg_violation(
    envelope: Envelope, home: Sequence[float], start: NED, target: Move
) -> Violation | None:
    breach = leg_breach(envelope, home, start, target.ned)
    if breach is None:
        return None
    leg = (ned_to_latlon(start[0], start[1], home), ned_to_latlon(*target.ned[:2], home))
    return Violation("geofence", f"The straight leg to the target {breach}.", leg)


# -- legs sent before the last one ends ------------------------------------------------------
# Rule: the agent sends a mission's steps one after another and only a `wait_for_flight`
# waits for the drone to arrive (a `sleep` waits a time, not an arrival). A move sent while
# earlier moves are still under way (no wait_for_flight since the first of them) may be
# flown from anywhere the drone can be by then: a step-by-step drone turns to the new
# target from where it is, an autopilot mission flies through the earlier targets. The
# drone is within the hull of where the unfinished moves began and of their targets, so
# the new leg is checked as a fan: from origins spaced along that hull's boundary (both
# ends of an unfinished leg among them, so the planned leg from the previous target and
# the shortcut from where the moves began are both in it), all to the new target. A leg
# from inside the hull is part of a fan leg from its boundary (the same line, longer),
# and between two neighbouring fan legs lies a sliver at most the spacing wide at its
# base: the fan covers the swept triangle to within the spacing.
#
# Spacing: FAN_SPACING_M (10 m), five times the corridor radius and the waypoint
# tolerance (2 m): a fence edge, an exclusion or published zone, a reservation or a rise
# of the terrain narrower than 10 m at the base of the fan is the only thing it can
# miss. At most FAN_MAX_ORIGINS origins per leg (about 640 m of unfinished boundary at
# 10 m): beyond it the spacing grows to the boundary's length over the cap, and with
# more hull corners than the cap the corners alone are the origins.
FAN_SPACING_M = 10.0
FAN_MAX_ORIGINS = 64
SHORTCUT_NOTE = (
    " It is sent while the moves before it are still under way (no wait_for_flight since"
    " them), so the drone may turn to it from anywhere along them; a wait_for_flight"
    " before it makes the drone fly through the previous target."
)


# A drone within this horizontal distance of its last target has reached it: the waypoint
# tolerance ([Paula 2018] algorithm 1), as the airspace corridors' radius.
ARRIVED_M = 2.0
FROM_HERE_NOTE = " (flown from where the drone is now: it is still on its way to its last target)"


def hull_distance(unfinished: Sequence[NED], point: NED) -> float:
    """Horizontal metres from `point` to the hull of `unfinished` (0 inside it): how far
    the drone surely still is from a new target when it is sent (see `fan_origins`)."""
    corners = hull_corners(unfinished)
    if not corners:
        return math.inf
    p = point[:2]
    if len(corners) > 2 and all(
        _cross(a[:2], b[:2], p) >= 0
        for a, b in zip(corners, corners[1:] + corners[:1], strict=True)
    ):
        return 0.0
    sides = (
        zip(corners, corners[1:] + corners[:1], strict=True)
        if len(corners) > 1
        else [(corners[0], corners[0])]
    )
    return min(_side_distance(a[:2], b[:2], p) for a, b in sides)


def _side_distance(a: Sequence[float], b: Sequence[float], p: Sequence[float]) -> float:
    dn, de = b[0] - a[0], b[1] - a[1]
    length = dn * dn + de * de
    share = (
        0.0
        if length == 0
        else max(0.0, min(1.0, ((p[0] - a[0]) * dn + (p[1] - a[1]) * de) / length))
    )
    return math.dist(p, (a[0] + share * dn, a[1] + share * de))


def command_starts(last: NED | None, here: NED | None) -> list[NED | None]:
    """Where the drone checks a command's leg from: its last target (the planned leg), and,
    while it is still flying to that target (farther than ARRIVED_M from it), where it is
    now, since it turns to the new target from there. The fan rule above for one command,
    where the drone knows where it is: its last-resort check of the ground's rule."""
    if last is None:
        return [here]
    if here is None or math.dist(here[:2], last[:2]) <= ARRIVED_M:
        return [last]
    return [last, here]


def hull_corners(points: Sequence[NED]) -> list[NED]:
    """The corners of the points' convex hull in the horizontal plane, in order (a point
    repeated horizontally keeps its latest height; collinear points give the two ends)."""
    latest = {(round(p[0], 3), round(p[1], 3)): p for p in points}
    ordered = sorted(latest.values(), key=lambda p: (p[0], p[1]))
    if len(ordered) < 3:
        return ordered

    def half(seq: Sequence[NED]) -> list[NED]:
        kept: list[NED] = []
        for p in seq:
            while len(kept) >= 2 and _cross(kept[-2][:2], kept[-1][:2], p[:2]) <= 0:
                kept.pop()
            kept.append(p)
        return kept[:-1]

    return half(ordered) + half(ordered[::-1])


def _along(a: NED, b: NED, share: float) -> NED:
    return (
        a[0] + share * (b[0] - a[0]),
        a[1] + share * (b[1] - a[1]),
        a[2] + share * (b[2] - a[2]),
    )


def fan_origins(
    unfinished: Sequence[NED], spacing: float = FAN_SPACING_M, cap: int = FAN_MAX_ORIGINS
) -> list[NED]:
    """Where the fan legs of a move start (see the rule above): `unfinished` holds where
    the moves under way began and their targets (or just their hull's corners), the last
    being the new leg's planned start (its previous target). Points of the boundary of
    their hull, at most `spacing` apart (coarser past `cap` points), heights linear along
    each side; none within MIN_LEG of the planned start (its leg is the planned one).
    Empty when no move is under way."""
    corners = hull_corners(unfinished)
    if len(corners) < 2:
        return []
    sides = list(zip(corners, corners[1:] + corners[:1], strict=True))
    if len(corners) == 2:
        sides = sides[:1]  # a straight line: along it once, its far end added below
    lengths = [math.dist(a[:2], b[:2]) for a, b in sides]
    step = max(spacing, sum(lengths) / max(1, cap - len(sides)))
    points = [
        _along(a, b, i / parts)
        for (a, b), length in zip(sides, lengths, strict=True)
        for parts in (max(1, math.ceil(length / step)),)
        for i in range(parts)
    ]
    if len(corners) == 2:
        points.append(corners[1])
    planned = unfinished[-1]
    return [p for p in points if math.dist(p[:2], planned[:2]) >= MIN_LEG]


# -- the check ----------------------------------------------------------------------------


def _is_return(move: Move) -> bool:
    return move.kind == "goto" and math.hypot(move.ned[0], move.ned[1]) <= RETURN_RADIUS


def check(
    envelope: Envelope,
    home: Sequence[float] | None,
    target: Move,
    airborne: bool,
    battery: float | None,
    start: NED | None = None,
) -> Violation | None:
    """The first limit `target` breaks, as a sentence naming it, or None.

    `home` is (lat, lon) of the drone's home; `battery` the remaining charge in percent;
    `start` where the drone flies the leg from (its current target), when known.
    Landing is always allowed: refusing it could only keep the drone in the air.
    """
    if target.kind == "land":
        return None
    north, east, down = target.ned
    height, distance = -down, math.hypot(north, east)
    if battery is not None and battery < envelope.battery_reserve and not _is_return(target):
        return Violation(
            "battery_reserve",
            f"The battery is at {battery:.0f} %, below the envelope's reserve of "
            f"{envelope.battery_reserve:g} %: only land and return home are accepted.",
        )
    if height > envelope.max_height:
        return Violation(
            "max_height",
            f"The target is {height:.1f} m above home, above the envelope's maximum height "
            f"of {envelope.max_height:g} m.",
        )
    if distance > envelope.max_distance:
        return Violation(
            "max_distance",
            f"The target is {distance:.0f} m from home, beyond the envelope's maximum "
            f"distance of {envelope.max_distance:g} m.",
        )
    if airborne and target.horizontal and height < envelope.min_move_height:
        return Violation(
            "min_move_height",
            f"Horizontal moves need at least the envelope's minimum height of "
            f"{envelope.min_move_height:g} m above home; the target is at {height:.1f} m.",
        )
    if home is not None:
        breach = local_fence_breach(envelope, home, (north, east))
        if breach is not None:
            return Violation("geofence", f"The target is {breach}.")
        if start is not None and target.kind == "goto":
            return _leg_violation(envelope, home, start, target)
    return None


# -- resolving commands to moves ------------------------------------------------------------


def resolve(
    command: str,
    params: Mapping[str, Any],
    base: NED | None,
    here: NED | None,
    home: Sequence[float] | None,
) -> Move | None:
    """The move a validated navigation command asks for, as the Navigation Processor plans it.

    Relative commands add to `base` (the drone's current target); takeoff and land start
    from `here` (its position). None for commands that do not move the drone, or when the
    position needed is unknown (the drone then decides, with its own check).
    """
    if command == "takeoff":
        start = here or base or (0.0, 0.0, 0.0)
        return Move("takeoff", (start[0], start[1], -float(params.get("altitude", 10.0))))
    if command == "land":
        origin = here or base
        return None if origin is None else Move("land", (origin[0], origin[1], 0.0))
    if base is None or command not in ("changeN", "changeE", "altitude", "navigate"):
        return None
    north, east, down = base
    if command == "changeN":
        return Move("goto", (north + params["value"], east, down), horizontal=True)
    if command == "changeE":
        return Move("goto", (north, east + params["value"], down), horizontal=True)
    if command == "altitude":
        return Move("goto", (north, east, down - params["value"]))
    if home is None:
        return None
    target_n, target_e = latlon_to_ne(params["lat"], params["lon"], home)
    return Move("goto", (target_n, target_e, down - params.get("altitude_delta", 0.0)), True)


@dataclass(frozen=True)
class StepViolation:
    index: int
    violation: Violation


@dataclass(frozen=True)
class WalkedLeg:
    """One leg of a mission walked from its start: the step's index and move, where the
    leg starts and whether the drone is airborne before it. `shortcut`: one of the step's
    fan legs (see `fan_origins`), flown from a point of the moves still under way, not
    from the previous target."""

    index: int
    move: Move
    start: NED | None
    airborne: bool
    shortcut: bool = False


def walk_legs(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: NED | None,
    airborne: bool,
) -> Iterator[WalkedLeg]:
    """Each moving step of a mission flown from `start`: its planned leg from the previous
    target, then, for a move sent while earlier ones are under way, its fan legs from the
    points of the unfinished moves (`fan_origins`). Refused steps are walked as if flown."""
    target = start
    # Where the drone was when no move was under way (the start, the target a
    # wait_for_flight reached) and every target sent since: it is within their hull, kept
    # as its corners (the hull of them and a new target is the hull of all and it).
    unfinished: list[NED] = [] if start is None else [start]
    for index, step in enumerate(steps):
        command = step["command"]
        if command == "wait_for_flight":
            unfinished = [] if target is None else [target]
            continue
        move = resolve(command, step.get("params") or {}, target, target, home)
        if move is None:
            continue
        yield WalkedLeg(index, move, target, airborne)
        if move.kind == "goto" and target is not None:
            for origin in fan_origins([*unfinished, target]):
                if math.dist(origin[:2], move.ned[:2]) >= MIN_LEG:
                    yield WalkedLeg(index, move, origin, airborne, shortcut=True)
        unfinished = hull_corners([*unfinished, move.ned])
        target = move.ned
        # Only a takeoff lifts a drone off and only a land puts it down; a move does not.
        airborne = {"takeoff": True, "land": False}.get(move.kind, airborne)


def walk(
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: NED | None,
    airborne: bool,
    shortcuts: bool = True,
) -> Iterator[tuple[int, Move, NED | None, bool]]:
    """Each leg of a mission flown from `start` (`walk_legs`) as (index, move, the leg's
    start, airborne before it): a step's planned leg first, then its fan legs, with the
    same index and move. `shortcuts=False`: the planned legs only (the path as drawn)."""
    for leg in walk_legs(home, steps, start, airborne):
        if shortcuts or not leg.shortcut:
            yield leg.index, leg.move, leg.start, leg.airborne


def step_violations(
    envelope: Envelope,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: NED | None,
    airborne: bool,
    battery: float | None,
) -> list[StepViolation]:
    """Walk a mission's steps from `start`: every step whose move (or leg) breaks the
    envelope.

    The walk goes on past a refused step as if it had been flown, so a planner can mark
    every offending step at once.
    """
    found: dict[int, StepViolation] = {}
    for leg in walk_legs(home, steps, start, airborne):
        if leg.index in found:
            continue  # one refusal per step: its planned leg's, else its first fan leg's
        violation = check(envelope, home, leg.move, leg.airborne, battery, leg.start)
        if violation is not None and leg.shortcut:
            violation = replace(violation, message=violation.message + SHORTCUT_NOTE)
        if violation is not None:
            found[leg.index] = StepViolation(leg.index, violation)
    return list(found.values())


def beyond_defaults(target: Move) -> Violation | None:
    """The default limit a move goes beyond, or None.

    An organisation may raise its limits above the defaults (DEFAULT_MAX_HEIGHT,
    DEFAULT_MAX_DISTANCE); a move beyond them is then allowed, but only once an operator
    has confirmed it. Landing never needs a confirmation.
    """
    if target.kind == "land":
        return None
    north, east, down = target.ned
    height, distance = -down, math.hypot(north, east)
    if height > DEFAULT_MAX_HEIGHT:
        return Violation(
            "max_height",
            f"The target is {height:.1f} m above home, above the default maximum height "
            f"of {DEFAULT_MAX_HEIGHT:g} m; confirm to fly beyond the defaults.",
        )
    if distance > DEFAULT_MAX_DISTANCE:
        return Violation(
            "max_distance",
            f"The target is {distance:.0f} m from home, beyond the default maximum "
            f"distance of {DEFAULT_MAX_DISTANCE:g} m; confirm to fly beyond the defaults.",
        )
    return None


def steps_beyond_defaults(
    home: Sequence[float] | None, steps: Sequence[Mapping[str, Any]], start: NED | None
) -> list[StepViolation]:
    """Every step of a mission flown from `start` whose move goes beyond the defaults."""
    found = []
    for index, move, _, _ in walk(home, steps, start, False, shortcuts=False):
        beyond = beyond_defaults(move)
        if beyond is not None:
            found.append(StepViolation(index, beyond))
    return found


def check_steps(
    envelope: Envelope,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: NED | None,
    airborne: bool,
    battery: float | None,
) -> StepViolation | None:
    """The first mission step whose move breaks the envelope, or None."""
    found = step_violations(envelope, home, steps, start, airborne, battery)
    return found[0] if found else None


# -- the drone's own guard ------------------------------------------------------------------


class EnvelopeGuard:
    """The envelope a drone enforces: the last one received, kept in `path` across restarts.

    Until one arrives the defaults apply, so a drone never flies unlimited. `state` is the
    flight controller's VehicleState (home, position, battery 0..1, airborne).
    """

    def __init__(self, path: Path | None = None) -> None:
        self.path = path
        self._lock = threading.Lock()
        self._envelope = Envelope()
        self.outside: Violation | None = None
        if path is not None and path.exists():
            try:
                self._envelope = parse_envelope(json.loads(path.read_text()))
            except (OSError, ValueError) as exc:
                log.warning("ignoring the stored envelope %s: %s", path, exc)

    @property
    def envelope(self) -> Envelope:
        with self._lock:
            return self._envelope

    def update(self, data: Mapping[str, Any]) -> Envelope:
        """Adopt a received envelope (already validated) and store it atomically."""
        envelope = parse_envelope(dict(data))
        with self._lock:
            self._envelope = envelope
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            partial = self.path.with_suffix(".partial")
            partial.write_text(json.dumps(envelope.to_dict()))
            os.replace(partial, self.path)
        return envelope

    def refusal(
        self,
        command: str,
        kind: str,
        ned: NED,
        state: Any,
        in_mission: bool = False,
        start: NED | None = None,
    ) -> str | None:
        """Why the drone refuses to fly to `ned` for `command` (the leg from `start`), or None.

        The battery reserve is checked on control commands, not on the steps of a mission
        already flying: there the fail-safe's battery alarm decides, and the ground hands
        the rest of the mission to another drone.
        """
        home = None if state.home is None else state.home[:2]
        move = Move(kind, ned, command in HORIZONTAL_COMMANDS)
        battery = None if in_mission else _percent(state)
        violation = check(self.envelope, home, move, state.airborne, battery, start)
        return None if violation is None else f"Outside the flight envelope: {violation.message}"

    def breach(self, ned: NED | None, state: Any) -> Violation | None:
        """The limit an airborne drone at `ned` is beyond (wind, bad GPS), or None."""
        if ned is None or not state.airborne:
            return None
        home = None if state.home is None else state.home[:2]
        envelope = replace(self.envelope, battery_reserve=0.0, min_move_height=0.0)
        return check(envelope, home, Move("goto", ned), True, None)


def _percent(state: Any) -> float | None:
    remaining = getattr(state, "battery_remaining", None)
    return None if remaining is None else remaining * 100.0

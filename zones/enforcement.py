"""Published zones on every move: a leg (or a point) inside a zone's volume while it
applies is refused, like the envelope's exclusion zones, within the zone's altitude band.

Prohibited zones refuse always; zones requiring authorisation refuse unless the
organisation recorded one that has not expired; conditional zones are shown, not refused
(their conditions are in their message). Heights are metres above the drone's home
(zones/bands.py places each band there). A drone already inside a zone's volume in the
air may fly out of it (as with the geofence: wind, or a zone published meanwhile); its
target is checked anyway. Time is now: a command is sent now, a mission starts now.

A sideways leg flown while a climb is under way (no `wait_for_flight` after a take-off or
a climb; a command to a drone still climbing; terrain/climbout.py) passes lower than the
straight line: `d` metres along it the drone may be anywhere from the height it has
surely reached, min(target, h0 + s·d), up to the highest height it was sent to. A zone
whose band meets that range over the zone is crossed, as is one the straight line meets.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from functools import cached_property
from typing import Any

from django.db.models import Exists, OuterRef, Q
from django.utils import timezone

import terrain
from onboard import envelope as env
from terrain.climbout import Climb, Paced
from terrain.guard import leg_climbs

from .bands import Band
from .models import Authorisation, Restriction, Zone
from .windows import applies_at

ZONE = "zone"
ENFORCED = (Restriction.PROHIBITED, Restriction.AUTHORISATION_REQUIRED)


@dataclass(frozen=True)
class ZoneViolation(env.Violation):
    """A move a published zone refuses; `code` is the API's error code."""

    code: str = ZONE


@dataclass(eq=False)
class Volume:
    """One zone as the checks see it: its shapes as an envelope of exclusions, and its
    band about home."""

    zone: Zone
    # Metres above mean sea level of the drone's home, from imported terrain (else None).
    home_elevation: float | None = None

    @cached_property
    def fence(self) -> env.Envelope:
        polygons, circles = [], []
        for shape in self.zone.shapes:
            if shape["type"] == "polygon":
                polygons.append(env.Polygon(False, tuple(tuple(p) for p in shape["points"])))
            else:
                circles.append(env.Circle(False, tuple(shape["center"]), shape["radius"]))
        return env.Envelope(polygons=tuple(polygons), circles=tuple(circles))

    @cached_property
    def band(self) -> Band:
        z = self.zone
        return Band(z.lower_m, z.lower_ref, z.upper_m, z.upper_ref)

    def covers(self, home: Sequence[float], point: env.NED) -> bool:
        lower, upper = self.band.about_home(self.home_elevation)
        return lower <= -point[2] <= upper and self.over(home, point)

    def over(self, home: Sequence[float], point: env.NED) -> bool:
        return env.local_fence_breach(self.fence, home, (point[0], point[1])) is not None

    def crossed(self, home: Sequence[float], start: env.NED, end: env.NED) -> bool:
        """Does the part of the leg within the band pass over the zone?"""
        span = band_span(-start[2], -end[2], *self.band.about_home(self.home_elevation))
        return self.passes(home, start, end, span)

    def crossed_climbing(
        self, home: Sequence[float], start: env.NED, end: env.NED, climb: Climb
    ) -> bool:
        """Does the part of the leg flown while climbing where the drone may be within
        the band pass over the zone?"""
        span = slant_span(climb, start, end, *self.band.about_home(self.home_elevation))
        return self.passes(home, start, end, span)

    def passes(
        self,
        home: Sequence[float],
        start: env.NED,
        end: env.NED,
        span: tuple[float, float] | None,
    ) -> bool:
        """Does the stretch `span` (fractions of the leg) pass over the zone?"""
        if span is None:
            return False
        a, b = (_along(start, end, t) for t in span)
        if self.over(home, a) or self.over(home, b):
            return True
        return env.leg_breach(self.fence, home, a, b) is not None

    def describe(self) -> str:
        """`the published zone 'Name' (ID, prohibited, 0 m AGL – 60 m AGL …).` and, where
        one would open it, that no authorisation is recorded."""
        z = self.zone
        kind = z.get_restriction_display().lower()
        text = f"the published zone {z.name!r} ({z.identifier}, {kind}, {self.band.text(self.home_elevation)})."
        if z.restriction == Restriction.AUTHORISATION_REQUIRED:
            text += " No valid authorisation is recorded for it."
        return text


def band_span(h0: float, h1: float, lower: float, upper: float) -> tuple[float, float] | None:
    """The fractions (t0, t1) of a leg climbing linearly from h0 to h1 where its height is
    within [lower, upper], or None."""
    if h0 == h1:
        return (0.0, 1.0) if lower <= h0 <= upper else None
    ends = sorted(((lower - h0) / (h1 - h0), (upper - h0) / (h1 - h0)))
    t0, t1 = max(ends[0], 0.0), min(ends[1], 1.0)
    return (t0, t1) if t0 <= t1 else None


def slant_span(
    climb: Climb, start: env.NED, end: env.NED, lower: float, upper: float
) -> tuple[float, float] | None:
    """The fractions (0, t1) of a leg flown while climbing where the heights the drone may
    be at, [min(target, h0 + s·d), the highest sent], meet [lower, upper]: from the leg's
    start to where the height surely reached passes `upper`, or None."""
    target = -end[2]
    highest = max(-start[2], target, climb.start)
    if highest < lower or climb.least(0.0, target) > upper:
        return None
    length = math.hypot(end[0] - start[0], end[1] - start[1])
    if target <= upper or length <= 0.0:
        return (0.0, 1.0)
    return (0.0, min(1.0, climb.reaches(upper) / length))


def _along(start: env.NED, end: env.NED, t: float) -> env.NED:
    return tuple(s + t * (e - s) for s, e in zip(start, end, strict=True))  # type: ignore[return-value]


# -- which zones ---------------------------------------------------------------------------


def candidates(
    organisation: Any, home: Sequence[float], points: Sequence[env.NED], at: datetime
) -> list[Volume]:
    """The enforced zones of the organisation (and site-wide ones) near the points, that
    apply at `at` and that the organisation holds no valid authorisation for: one query."""
    latlons = [env.ned_to_latlon(p[0], p[1], home) for p in points]
    lats, lons = [p[0] for p in latlons], [p[1] for p in latlons]
    valid = Authorisation.objects.filter(
        organisation=organisation, zone=OuterRef("pk"), expires_at__gt=at
    )
    zones = Zone.objects.filter(
        Q(organisation=organisation) | Q(organisation__isnull=True),
        ~Exists(valid),
        restriction__in=ENFORCED,
        min_lat__lte=max(lats),
        max_lat__gte=min(lats),
        min_lon__lte=max(lons),
        max_lon__gte=min(lons),
    )
    found = [z for z in zones if applies_at(z.applicability, at)]
    amsl = any("AMSL" in (z.lower_ref, z.upper_ref) for z in found)
    elevation = terrain.elevation(*home[:2]) if amsl else None
    return [Volume(z, elevation) for z in found]


# -- the checks ------------------------------------------------------------------------------


def leg_violation(
    volumes: Sequence[Volume],
    home: Sequence[float],
    start: env.NED | None,
    move: env.Move,
    airborne: bool,
    climb: Climb | None = None,
) -> ZoneViolation | None:
    """The first zone the move's target is inside of, or its leg crosses (flown on a slant
    from `climb` when a climb is under way as it leaves)."""
    if move.kind == "land":
        return None  # landing is always allowed, as by the envelope
    end = move.ned
    if move.kind == "takeoff":
        start = (end[0], end[1], start[2] if start else 0.0)
    for volume in volumes:
        if volume.covers(home, end):
            return ZoneViolation(ZONE, f"The target is inside {volume.describe()}")
        if start is None or (airborne and volume.covers(home, start)):
            continue
        leg = (env.ned_to_latlon(*start[:2], home), env.ned_to_latlon(*end[:2], home))
        if volume.crossed(home, start, end):
            return ZoneViolation(
                ZONE, f"The straight leg to the target crosses {volume.describe()}", leg
            )
        if climb is not None and volume.crossed_climbing(home, start, end, climb):
            return ZoneViolation(ZONE, _climbing_message(climb, end, volume), leg)
    return None


def _climbing_message(climb: Climb, end: env.NED, volume: Volume) -> str:
    rate = f", surely climbing only 1 m per {1 / climb.slope:.1f} m along it" if climb.slope > 0 else ""  # fmt: skip
    return (
        "The leg to the target is flown while the drone is still climbing (no "
        f"wait_for_flight after the climb): from {climb.start:.1f} m above home{rate} to "
        f"{-end[2]:.1f} m, it crosses {volume.describe()}"
    )


def move_violation(
    organisation: Any,
    home: Sequence[float] | None,
    move: env.Move,
    start: env.NED | None,
    airborne: bool,
    at: datetime | None = None,
    climb: Climb | None = None,
) -> ZoneViolation | None:
    """What fleet/envelopes.py asks for a command's move (from `start`, the drone's
    current target), at `at` (now); `climb`: the climb under way when it is sent
    (fleet/envelopes.py command_climb)."""
    if home is None or move.kind == "land":
        return None
    points = [move.ned] if start is None else [start, move.ned]
    volumes = candidates(organisation, home, points, at or timezone.now())
    return leg_violation(volumes, home, start, move, airborne, climb)


def step_violations(
    organisation: Any,
    home: Sequence[float] | None,
    steps: Sequence[Mapping[str, Any]],
    start: env.NED | None,
    airborne: bool,
    at: datetime | None = None,
    pace: Paced | None = None,
    climbing_from: float | None = None,
) -> list[env.StepViolation]:
    """Every mission step whose move or leg a published zone refuses, walked as the
    envelope walks them (onboard/envelope.py `walk`); the legs flown while a climb is
    under way at the drone's `pace` (terrain/guard.py leg_climbs, `climbing_from`: the
    height of a drone still climbing to `start`), fan legs included."""
    if home is None:
        return []
    legs = list(env.walk(home, steps, start, airborne))
    points = [p for _, move, leg_start, _ in legs for p in (move.ned, leg_start) if p]
    if not points:
        return []
    volumes = candidates(organisation, home, points, at or timezone.now())
    if not volumes:
        return []
    walked = [(index, move, leg_start) for index, move, leg_start, _ in legs]
    climbs = leg_climbs(home, steps, start, walked, pace, climbing_from)
    found: dict[int, env.StepViolation] = {}  # one refusal per step, as the envelope's
    for index, move, leg_start, flying in legs:
        if index in found:
            continue
        climb = climbs.get((index, leg_start), climbs.get(index))
        violation = leg_violation(volumes, home, leg_start, move, flying, climb)
        if violation is not None:
            found[index] = env.StepViolation(index, violation)
    return list(found.values())

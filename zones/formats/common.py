"""What every zone file reader produces, and the checks they share.

A reader turns a file into ParsedZones or raises ZoneFileError naming the field (a dotted
path into the file) and the problem; nothing is stored until a whole file has been read.
Shapes are checked by the envelope's own geofence rules (onboard/envelope.py: at least
three distinct points, no self-intersection, latitudes within ±89°).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from onboard import envelope as env

from ..bands import Band, BandError, checked_band, reference, to_metres
from ..windows import WindowError

RESTRICTIONS = ("prohibited", "authorisation_required", "conditional")
# ED-269 restriction words → ours; NO_RESTRICTION zones carry no rule and are skipped.
ED269_RESTRICTIONS = {
    "PROHIBITED": "prohibited",
    "REQ_AUTHORISATION": "authorisation_required",
    "CONDITIONAL": "conditional",
    "NO_RESTRICTION": None,
}
MAX_TEXT = 200
MAX_MESSAGE = 2000
# A zone's identifier is stored in a column this wide (zones.models.Zone.identifier).
MAX_IDENTIFIER = 120


class ZoneFileError(ValueError):
    """A file refused as a whole: `field` names where, `message` what."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.field = field
        self.message = message


@dataclass(frozen=True)
class ParsedZone:
    identifier: str
    name: str
    restriction: str
    shapes: list[dict]
    band: Band
    applicability: list[dict] = field(default_factory=list)
    message: str = ""
    part: int = 0


@dataclass
class Budget:
    """What one file may hold: vertices in all, counted as shapes are read."""

    max_vertices: int
    max_zones: int
    vertices: int = 0

    def spend(self, count: int, where: str) -> None:
        self.vertices += count
        if self.vertices > self.max_vertices:
            raise ZoneFileError(where, f"the file has more than {self.max_vertices} vertices")


def text(value: object, where: str, *, required: bool = True, limit: int = MAX_TEXT) -> str:
    if value is None and not required:
        return ""
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str) or (required and not value.strip()):
        raise ZoneFileError(where, "must be a non-empty text")
    if len(value) > limit:
        raise ZoneFileError(where, f"longer than {limit} characters")
    return value.strip()


def restriction(value: object, where: str) -> str | None:
    """Ours, or ED-269's words; None for NO_RESTRICTION."""
    if isinstance(value, str) and value.lower() in RESTRICTIONS:
        return value.lower()
    if isinstance(value, str) and value.upper() in ED269_RESTRICTIONS:
        return ED269_RESTRICTIONS[value.upper()]
    raise ZoneFileError(
        where,
        f"unknown restriction {value!r}; expected PROHIBITED, REQ_AUTHORISATION, "
        "CONDITIONAL or NO_RESTRICTION (or prohibited, authorisation_required, conditional)",
    )


def band(limits: Mapping[str, Any], where: str) -> Band:
    """lowerLimit, upperLimit, their unit (uomDimensions) and references, as ED-269 names
    them; any missing or unknown one refuses the zone."""
    unit = limits.get("uomDimensions")
    missing = [
        key
        for key in (
            "lowerLimit",
            "upperLimit",
            "uomDimensions",
            "lowerVerticalReference",
            "upperVerticalReference",
        )
        if limits.get(key) is None
    ]
    if missing:
        raise ZoneFileError(where, f"the altitude band is unknown: no {', '.join(missing)}")
    try:
        return checked_band(
            Band(
                to_metres(limits["lowerLimit"], unit, f"{where}.lowerLimit"),
                reference(limits["lowerVerticalReference"], f"{where}.lowerVerticalReference"),
                to_metres(limits["upperLimit"], unit, f"{where}.upperLimit"),
                reference(limits["upperVerticalReference"], f"{where}.upperVerticalReference"),
            ),
            where,
        )
    except BandError as exc:
        raise ZoneFileError(exc.field, exc.message) from None


def lonlat(point: object, where: str) -> list[float]:
    """A [longitude, latitude(, altitude)] position (RFC 7946 §3.1.1, ED-269) → [lat, lon]."""
    if (
        not isinstance(point, list | tuple)
        or len(point) < 2
        or not all(_finite(v) for v in point[:2])
    ):
        raise ZoneFileError(where, f"must be [longitude, latitude], got {point!r}")
    return [float(point[1]), float(point[0])]


def _finite(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def polygon(ring: Sequence[list[float]], where: str, budget: Budget) -> dict:
    """A ring of [lat, lon] checked as a geofence polygon is."""
    budget.spend(len(ring), where)
    try:
        (parsed,), _ = env.parse_geofence(
            {"polygons": [{"inclusion": False, "polygon": [list(p) for p in ring]}]}, where
        )
    except env.EnvelopeError as exc:
        raise ZoneFileError(where, _shape_problem(exc, where)) from None
    return {"type": "polygon", "points": [list(p) for p in parsed.points]}


def circle(center: list[float], radius_m: float, where: str, budget: Budget) -> dict:
    budget.spend(1, where)
    try:
        _, (parsed,) = env.parse_geofence(
            {"circles": [{"inclusion": False, "circle": {"center": center, "radius": radius_m}}]},
            where,
        )
    except env.EnvelopeError as exc:
        raise ZoneFileError(where, _shape_problem(exc, where)) from None
    return {"type": "circle", "center": list(parsed.center), "radius": parsed.radius}


def _shape_problem(exc: env.EnvelopeError, where: str) -> str:
    detail = exc.field.removeprefix(where).lstrip(".")
    return f"bad geometry ({detail}: {exc.message})" if detail else f"bad geometry: {exc.message}"


def windows_error(exc: WindowError) -> ZoneFileError:
    return ZoneFileError(exc.field, exc.message)


def distinct(zones: list[ParsedZone], budget: Budget) -> list[ParsedZone]:
    """The zones, refused when an identifier repeats or there are too many."""
    if len(zones) > budget.max_zones:
        raise ZoneFileError("features", f"more than {budget.max_zones} zones")
    seen: set[tuple[str, int]] = set()
    for zone in zones:
        key = (zone.identifier, zone.part)
        if key in seen:
            raise ZoneFileError("identifier", f"{zone.identifier!r} appears twice")
        seen.add(key)
    return zones

"""EUROCAE ED-269 zone files, the JSON form EU member states publish their UAS
geographical zones in [EUROCAE ED-269; EU 2019/947, Art. 15].

The document is an object whose `features` list the zones: `identifier`, `name`,
`restriction` (PROHIBITED, REQ_AUTHORISATION, CONDITIONAL, NO_RESTRICTION), `message`,
`applicability` (permanent YES/NO, startDateTime, endDateTime, schedule of day,
startTime, endTime) and `geometry`, a list of volumes, each with a `horizontalProjection`
(a GeoJSON-like Polygon, or a Circle with `center` [longitude, latitude] and `radius`),
`lowerLimit`, `upperLimit` and the radius in `uomDimensions` (M or FT), and
`lowerVerticalReference` / `upperVerticalReference` (AGL, AMSL, WGS84). Each volume
becomes one stored zone (`part`), since each has its own band. NO_RESTRICTION zones are
skipped: they restrict nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..bands import BandError, to_metres
from ..windows import WindowError, applicability
from .common import (
    MAX_IDENTIFIER,
    MAX_MESSAGE,
    Budget,
    ParsedZone,
    ZoneFileError,
    band,
    circle,
    distinct,
    lonlat,
    polygon,
    restriction,
    text,
    windows_error,
)

MAX_VOLUMES = 50


def read(document: Any, budget: Budget) -> list[ParsedZone]:
    if not isinstance(document, Mapping) or not isinstance(document.get("features"), list):
        raise ZoneFileError("features", "an ED-269 file is an object with a features list")
    zones: list[ParsedZone] = []
    for i, feature in enumerate(document["features"]):
        zones += _feature(feature, f"features[{i}]", budget)
        if len(zones) > budget.max_zones:
            break
    return distinct(zones, budget)


def _feature(feature: Any, where: str, budget: Budget) -> list[ParsedZone]:
    if not isinstance(feature, Mapping):
        raise ZoneFileError(where, "must be an object")
    kind = restriction(feature.get("restriction"), f"{where}.restriction")
    if kind is None:
        return []  # NO_RESTRICTION restricts nothing: skipped before its volumes are read
    identifier = text(feature.get("identifier"), f"{where}.identifier", limit=MAX_IDENTIFIER)
    name = text(feature.get("name") or identifier, f"{where}.name")
    volumes = feature.get("geometry")
    if not isinstance(volumes, list) or not volumes:
        raise ZoneFileError(f"{where}.geometry", "must be a non-empty list of volumes")
    if len(volumes) > MAX_VOLUMES:
        raise ZoneFileError(f"{where}.geometry", f"more than {MAX_VOLUMES} volumes")
    try:
        periods = applicability(feature.get("applicability"), f"{where}.applicability")
    except WindowError as exc:
        raise windows_error(exc) from None
    message = text(feature.get("message"), f"{where}.message", required=False, limit=MAX_MESSAGE)
    parts = [_volume(v, f"{where}.geometry[{j}]", budget) for j, v in enumerate(volumes)]
    return [
        ParsedZone(identifier, name, kind, [shape], limits, periods, message, part)
        for part, (shape, limits) in enumerate(parts)
    ]


def _volume(volume: Any, where: str, budget: Budget):  # type: ignore[no-untyped-def]
    if not isinstance(volume, Mapping):
        raise ZoneFileError(where, "must be an object")
    limits = band(volume, where)
    projection = volume.get("horizontalProjection")
    if not isinstance(projection, Mapping):
        raise ZoneFileError(f"{where}.horizontalProjection", "must be an object")
    where = f"{where}.horizontalProjection"
    if projection.get("type") == "Circle":
        return _circle(projection, volume.get("uomDimensions"), where, budget), limits
    if projection.get("type") == "Polygon":
        rings = projection.get("coordinates")
        if not isinstance(rings, list) or not rings or not isinstance(rings[0], list):
            raise ZoneFileError(f"{where}.coordinates", "must be a list of linear rings")
        if len(rings[0]) > budget.max_vertices:
            raise ZoneFileError(where, f"more than {budget.max_vertices} vertices")
        points = [lonlat(p, f"{where}.coordinates[0][{k}]") for k, p in enumerate(rings[0])]
        return polygon(points, where, budget), limits
    raise ZoneFileError(
        f"{where}.type", f"must be Polygon or Circle, got {projection.get('type')!r}"
    )


def _circle(projection: Mapping, unit: object, where: str, budget: Budget) -> dict:
    center = lonlat(projection.get("center"), f"{where}.center")
    try:
        radius = to_metres(projection.get("radius"), unit, f"{where}.radius")
    except BandError as exc:
        raise ZoneFileError(exc.field, exc.message) from None
    return circle(center, radius, where, budget)

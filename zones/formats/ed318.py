"""EUROCAE ED-318 geographical zone files: ED-269's successor, which states such as Ireland
and Sweden publish [EUROCAE ED-318].

A GeoJSON FeatureCollection. Read from each feature's `properties`: `identifier`, `name`
and `message` (a text, or a list of `{text, lang}` of which the English, else the first,
is kept), `type` (PROHIBITED, REQ_AUTHORIZATION, CONDITIONAL, NO_RESTRICTION, and
USPACE, read as CONDITIONAL) and `limitedApplicability` (ED-269's periods: startDateTime, endDateTime, schedule; absent,
the zone is permanent). Its `geometry` is a Polygon or MultiPolygon, a Point whose
`extent` is a Circle with a `radius`, or a GeometryCollection of those; each geometry
carries its own `layer` (`lower`, `upper`, `lowerReference`, `upperReference`, `uom`
m or ft, the radius's unit too) and becomes one stored zone (`part`). As in GeoJSON, only
a polygon's exterior ring is kept. NO_RESTRICTION zones are skipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..bands import Band, BandError, to_metres
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
    restriction,
    text,
    windows_error,
)
from .geojson import shapes

# ED-318's zone types in ED-269's words: it spells the authorisation the American way, and
# a U-space airspace asks for U-space services, not a refusal (drawn and listed, as a
# conditional zone is).
TYPES = {"REQ_AUTHORIZATION": "REQ_AUTHORISATION", "USPACE": "CONDITIONAL"}
ED318_TYPES = ("USPACE", "PROHIBITED", "REQ_AUTHORIZATION", "CONDITIONAL", "NO_RESTRICTION")
MAX_GEOMETRIES = 50


def is_ed318(document: Mapping) -> bool:
    """A FeatureCollection whose first zone says its ED-318 `type` where ED-269 says
    `restriction`, or carries its band as a geometry's `layer`."""
    features = document.get("features")
    first = features[0] if isinstance(features, list) and features else None
    if not isinstance(first, Mapping):
        return False
    props, geometry = first.get("properties"), first.get("geometry")
    typed = isinstance(props, Mapping) and "restriction" not in props
    return (typed and props.get("type") in ED318_TYPES) or (  # type: ignore[union-attr]
        isinstance(geometry, Mapping) and "layer" in geometry
    )


def read(document: Mapping, budget: Budget) -> list[ParsedZone]:
    features = document.get("features")
    if not isinstance(features, list):
        raise ZoneFileError("features", "must be a list")
    zones: list[ParsedZone] = []
    for i, feature in enumerate(features):
        zones += _feature(feature, f"features[{i}]", budget)
        if len(zones) > budget.max_zones:
            break
    return distinct(zones, budget)


def _feature(feature: Any, where: str, budget: Budget) -> list[ParsedZone]:
    props = feature.get("properties") if isinstance(feature, Mapping) else None
    if not isinstance(props, Mapping):
        raise ZoneFileError(where, "must be a Feature with properties")
    kind_of = props.get("type")
    kind = restriction(TYPES.get(kind_of, kind_of), f"{where}.properties.type")
    if kind is None:
        return []  # NO_RESTRICTION restricts nothing
    identifier = text(
        props.get("identifier"), f"{where}.properties.identifier", limit=MAX_IDENTIFIER
    )
    name = text(_localised(props.get("name")) or identifier, f"{where}.properties.name")
    message = text(
        _localised(props.get("message")),
        f"{where}.properties.message",
        required=False,
        limit=MAX_MESSAGE,
    )
    try:
        periods = applicability(
            props.get("limitedApplicability"), f"{where}.properties.limitedApplicability"
        )
    except WindowError as exc:
        raise windows_error(exc) from None
    parts = [
        _part(g, w, budget) for g, w in _geometries(feature.get("geometry"), f"{where}.geometry")
    ]
    return [
        ParsedZone(identifier, name, kind, found, limits, periods, message, part)
        for part, (found, limits) in enumerate(parts)
    ]


def _localised(value: Any) -> Any:
    """A text as it is; of a list of {text, lang}, the English one, else the first."""
    if not isinstance(value, list):
        return value
    texts = [v for v in value if isinstance(v, Mapping) and isinstance(v.get("text"), str)]
    english = [v for v in texts if str(v.get("lang", "")).lower().startswith("en")]
    return (english or texts or [{"text": None}])[0]["text"]


def _geometries(geometry: Any, where: str) -> list[tuple[Mapping, str]]:
    """The geometries that each carry a layer: a collection's members, else the one."""
    if not isinstance(geometry, Mapping):
        raise ZoneFileError(where, "must be a geometry object")
    if geometry.get("type") != "GeometryCollection":
        return [(geometry, where)]
    members = geometry.get("geometries")
    if not isinstance(members, list) or not members:
        raise ZoneFileError(f"{where}.geometries", "must be a non-empty list")
    if len(members) > MAX_GEOMETRIES:
        raise ZoneFileError(f"{where}.geometries", f"more than {MAX_GEOMETRIES} geometries")
    shared = geometry.get("layer")
    return [
        ({"layer": shared, **m} if isinstance(m, Mapping) else m, f"{where}.geometries[{i}]")
        for i, m in enumerate(members)
    ]


def _part(geometry: Any, where: str, budget: Budget) -> tuple[list[dict], Band]:
    if not isinstance(geometry, Mapping):
        raise ZoneFileError(where, "must be a geometry object")
    layer = geometry.get("layer")
    if not isinstance(layer, Mapping):
        raise ZoneFileError(f"{where}.layer", "the altitude band is unknown: no layer")
    unit = layer.get("uom").upper() if isinstance(layer.get("uom"), str) else layer.get("uom")
    limits = band(
        {
            "lowerLimit": layer.get("lower"),
            "upperLimit": layer.get("upper"),
            "uomDimensions": unit,
            "lowerVerticalReference": layer.get("lowerReference"),
            "upperVerticalReference": layer.get("upperReference"),
        },
        f"{where}.layer",
    )
    if geometry.get("type") == "Point":
        return [_circle(geometry, unit, where, budget)], limits
    return shapes(geometry, where, budget), limits


def _circle(point: Mapping, unit: Any, where: str, budget: Budget) -> dict:
    extent = point.get("extent")
    if not isinstance(extent, Mapping) or extent.get("subType") != "Circle":
        raise ZoneFileError(f"{where}.extent", "a Point zone needs a Circle extent with a radius")
    try:
        radius = to_metres(extent.get("radius"), unit, f"{where}.extent.radius")
    except BandError as exc:
        raise ZoneFileError(exc.field, exc.message) from None
    return circle(lonlat(point.get("coordinates"), f"{where}.coordinates"), radius, where, budget)

"""GeoJSON zone files: an RFC 7946 FeatureCollection of Polygon and MultiPolygon features.

Read from each feature's `properties` (the names ED-269 gives the same facts):
`identifier` (else the feature's `id`), `name`, `restriction` (PROHIBITED,
REQ_AUTHORISATION, CONDITIONAL, NO_RESTRICTION, or prohibited, authorisation_required,
conditional), `lowerLimit`, `upperLimit`, `uomDimensions` (M or FT),
`lowerVerticalReference`, `upperVerticalReference` (AGL, AMSL, WGS84), optionally
`message`, and `applicability` (ED-269's list) or `startDateTime`/`endDateTime`.
A missing band or unit refuses the file. Only the exterior ring of a polygon is kept:
holes are flown as part of the zone, which can only refuse more [RFC 7946 §3.1.6].
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..windows import WindowError, applicability
from .common import (
    MAX_IDENTIFIER,
    MAX_MESSAGE,
    Budget,
    ParsedZone,
    ZoneFileError,
    band,
    distinct,
    lonlat,
    polygon,
    restriction,
    text,
    windows_error,
)


def read(document: Any, budget: Budget) -> list[ParsedZone]:
    if not isinstance(document, Mapping) or document.get("type") != "FeatureCollection":
        raise ZoneFileError("type", "a GeoJSON zone file is a FeatureCollection")
    features = document.get("features")
    if not isinstance(features, list):
        raise ZoneFileError("features", "must be a list")
    found = (_feature(f, f"features[{i}]", budget) for i, f in enumerate(features))
    return distinct([zone for zone in found if zone is not None], budget)


def _feature(feature: Any, where: str, budget: Budget) -> ParsedZone | None:
    if not isinstance(feature, Mapping) or feature.get("type") != "Feature":
        raise ZoneFileError(where, "must be a GeoJSON Feature")
    props = feature.get("properties")
    if not isinstance(props, Mapping):
        raise ZoneFileError(f"{where}.properties", "must be an object")
    kind = restriction(props.get("restriction"), f"{where}.properties.restriction")
    if kind is None:
        return None
    identifier = props.get("identifier", feature.get("id"))
    return ParsedZone(
        identifier=text(identifier, f"{where}.properties.identifier", limit=MAX_IDENTIFIER),
        name=text(props.get("name"), f"{where}.properties.name"),
        restriction=kind,
        shapes=shapes(feature.get("geometry"), f"{where}.geometry", budget),
        band=band(props, f"{where}.properties"),
        applicability=_windows(props, f"{where}.properties"),
        message=text(
            props.get("message"), f"{where}.properties.message", required=False, limit=MAX_MESSAGE
        ),
    )


def shapes(geometry: Any, where: str, budget: Budget) -> list[dict]:
    """The exterior rings of a Polygon or MultiPolygon, each checked as a zone polygon."""
    if not isinstance(geometry, Mapping):
        raise ZoneFileError(where, "must be a Polygon or MultiPolygon geometry")
    kind, coordinates = geometry.get("type"), geometry.get("coordinates")
    if kind == "Polygon":
        polygons = [coordinates]
    elif kind == "MultiPolygon" and isinstance(coordinates, list):
        polygons = coordinates
    else:
        raise ZoneFileError(f"{where}.type", f"must be Polygon or MultiPolygon, got {kind!r}")
    return [_ring(rings, f"{where}.coordinates[{i}]", budget) for i, rings in enumerate(polygons)]


def _ring(rings: Any, where: str, budget: Budget) -> dict:
    if not isinstance(rings, list) or not rings or not isinstance(rings[0], list):
        raise ZoneFileError(where, "must be a list of linear rings")
    exterior = rings[0]
    if len(exterior) > budget.max_vertices:
        raise ZoneFileError(where, f"more than {budget.max_vertices} vertices")
    points = [lonlat(p, f"{where}[0][{j}]") for j, p in enumerate(exterior)]
    return polygon(points, where, budget)


def _windows(props: Mapping, where: str) -> list[dict]:
    try:
        if "applicability" in props:
            return applicability(props["applicability"], f"{where}.applicability")
        if props.get("startDateTime") is None and props.get("endDateTime") is None:
            return []
        entry = {k: props.get(k) for k in ("startDateTime", "endDateTime") if k in props}
        return applicability([{"permanent": "NO", **entry}], where)
    except WindowError as exc:
        raise windows_error(exc) from None

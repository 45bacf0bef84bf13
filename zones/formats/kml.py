"""KML zone files: Placemarks with Polygons (or MultiGeometry of Polygons) [OGC KML 2.2].

A polygon is its `outerBoundaryIs/LinearRing/coordinates` ("lon,lat[,alt]" tuples
separated by white space [OGC KML 2.2]); inner boundaries are flown as part
of the zone. KML has no altitude band of its own: it is read from the Placemark's
`ExtendedData` (`Data name=…><value>` or `SchemaData/SimpleData name=…`) under the names
ED-269 uses: `lowerLimit`, `upperLimit`, `uomDimensions`, `lowerVerticalReference`,
`upperVerticalReference`, with `restriction`, `identifier` (else the Placemark's id
attribute) and `message`. A Placemark without them is refused: its band is unknown.

The XML is read with the standard library after a first pass that refuses any document
type declaration: no DTD, so no entity can be declared, expanded or fetched (the
"billion laughs" and external entity attacks) [Python xml vulnerabilities].
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from xml.parsers import expat

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
    text,
)
from .common import restriction as restriction_of

BAND_KEYS = (
    "lowerLimit",
    "upperLimit",
    "uomDimensions",
    "lowerVerticalReference",
    "upperVerticalReference",
)


def _refuse_declarations(*_args: object) -> None:
    raise ZoneFileError("kml", "document type declarations and entities are refused")


def safe_tree(data: bytes) -> ET.Element:
    """The parsed document, refused when it declares a DTD or an entity."""
    guard = expat.ParserCreate()
    guard.StartDoctypeDeclHandler = _refuse_declarations
    guard.EntityDeclHandler = _refuse_declarations
    guard.ExternalEntityRefHandler = _refuse_declarations
    try:
        guard.Parse(data, True)
        return ET.fromstring(data)
    except (expat.ExpatError, ET.ParseError) as exc:
        raise ZoneFileError("kml", f"not well-formed XML: {exc}") from None


def _local(tag: object) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _children(element: ET.Element, name: str) -> list[ET.Element]:
    return [child for child in element if _local(child.tag) == name]


def _descendants(element: ET.Element, name: str) -> list[ET.Element]:
    return [node for node in element.iter() if _local(node.tag) == name]


def read(data: bytes, budget: Budget) -> list[ParsedZone]:
    root = safe_tree(data)
    if _local(root.tag) != "kml":
        raise ZoneFileError("kml", f"the root element is {_local(root.tag)!r}, not kml")
    placemarks = _descendants(root, "Placemark")
    if len(placemarks) > budget.max_zones:
        raise ZoneFileError("Placemark", f"more than {budget.max_zones} zones")
    found = (_placemark(p, f"Placemark[{i}]", budget) for i, p in enumerate(placemarks))
    return distinct([zone for zone in found if zone is not None], budget)


def extended_data(placemark: ET.Element) -> dict[str, str]:
    values: dict[str, str] = {}
    for data in _descendants(placemark, "Data"):
        value = _children(data, "value")
        if data.get("name") and value:
            values[data.get("name")] = (value[0].text or "").strip()  # type: ignore[index]
    for simple in _descendants(placemark, "SimpleData"):
        if simple.get("name"):
            values[simple.get("name")] = (simple.text or "").strip()  # type: ignore[index]
    return values


def _number(values: dict[str, str], key: str, where: str) -> float | str | None:
    raw = values.get(key)
    if raw is None or key in ("uomDimensions",) or "VerticalReference" in key:
        return raw
    try:
        return float(raw)
    except ValueError:
        raise ZoneFileError(f"{where}.{key}", f"must be a number, got {raw!r}") from None


def _placemark(placemark: ET.Element, where: str, budget: Budget) -> ParsedZone | None:
    values = extended_data(placemark)
    names = _children(placemark, "name")
    name = (names[0].text or "").strip() if names else ""
    kind = restriction_of(values.get("restriction", "PROHIBITED"), f"{where}.restriction")
    polygons = _descendants(placemark, "Polygon")
    if not polygons:
        raise ZoneFileError(where, "has no Polygon")
    limits = band({k: _number(values, k, where) for k in BAND_KEYS}, where)
    shapes = [_polygon(p, f"{where}.Polygon[{i}]", budget) for i, p in enumerate(polygons)]
    if kind is None:
        return None
    identifier = values.get("identifier") or placemark.get("id") or name
    return ParsedZone(
        identifier=text(identifier, f"{where}.identifier", limit=MAX_IDENTIFIER),
        name=text(name or identifier, f"{where}.name"),
        restriction=kind,
        shapes=shapes,
        band=limits,
        message=text(values.get("message"), f"{where}.message", required=False, limit=MAX_MESSAGE),
    )


def _polygon(element: ET.Element, where: str, budget: Budget) -> dict:
    outer = _children(element, "outerBoundaryIs")
    rings = _descendants(outer[0], "coordinates") if outer else []
    if not rings:
        raise ZoneFileError(where, "has no outerBoundaryIs/LinearRing/coordinates")
    tuples = (rings[0].text or "").split()
    if len(tuples) > budget.max_vertices:
        raise ZoneFileError(where, f"more than {budget.max_vertices} vertices")
    points = [lonlat(_tuple(t, f"{where}.coordinates[{i}]"), where) for i, t in enumerate(tuples)]
    return polygon(points, where, budget)


def _tuple(raw: str, where: str) -> list[float]:
    try:
        return [float(v) for v in raw.split(",")]
    except ValueError:
        raise ZoneFileError(where, f"not a lon,lat[,alt] tuple: {raw!r}") from None

"""Importing a zone file: read it whole, then replace the scope's zones in one transaction.

A file's zones replace those with the same identifiers in the same scope (one
organisation, or site-wide); other zones stay. A refused file changes nothing.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from django.conf import settings
from django.db import transaction

from onboard.envelope import ned_to_latlon

from .formats import ed269, ed318, geojson, kml
from .formats.common import Budget, ParsedZone, ZoneFileError
from .models import Zone

FORMATS = ("geojson", "ed269", "ed318", "kml")
UTF8_BOM = b"\xef\xbb\xbf"
ZIP_MAGIC = b"PK\x03\x04"


@dataclass(frozen=True)
class Imported:
    file_format: str
    zones: int
    updated: int


def budget() -> Budget:
    return Budget(max_vertices=settings.ZONES_MAX_VERTICES, max_zones=settings.ZONES_MAX_ZONES)


def detect(name: str, data: bytes) -> str:
    """The format of a file: KMZ (zipped KML) by its first bytes, KML by its name or its
    first character, else JSON: a FeatureCollection is GeoJSON or ED-318, any other object
    with features ED-269."""
    if data.startswith(ZIP_MAGIC):
        return "kmz"
    head = data.removeprefix(UTF8_BOM).lstrip()[:1]
    if name.lower().endswith(".kml") or head == b"<":
        return "kml"
    return "json"


def unzipped_kml(data: bytes) -> bytes:
    """The KML inside a KMZ (Google Earth's usual export): its doc.kml, else its first .kml,
    read no further than the file size limit, which the unzipped text is held to too."""
    limit = settings.ZONES_MAX_FILE_BYTES
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            entries = [e for e in archive.infolist() if e.filename.lower().endswith(".kml")]
            if not entries:
                raise ZoneFileError("kmz", "holds no .kml file")
            entry = next((e for e in entries if e.filename.lower() == "doc.kml"), entries[0])
            with archive.open(entry) as inside:
                text = inside.read(limit + 1)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError) as exc:
        raise ZoneFileError("kmz", f"not a readable KMZ (zip) file: {exc}") from None
    if len(text) > limit:
        raise ZoneFileError(f"kmz:{entry.filename}", f"larger than {limit} bytes unzipped")
    return text


def _json(data: bytes) -> Any:
    try:
        return json.loads(data.decode("utf-8-sig"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ZoneFileError("", f"not valid JSON: {exc}") from None


def parse(name: str, data: bytes) -> tuple[str, list[ParsedZone]]:
    """(format, zones) of a file, or ZoneFileError; stores nothing."""
    if len(data) > settings.ZONES_MAX_FILE_BYTES:
        raise ZoneFileError("", f"larger than {settings.ZONES_MAX_FILE_BYTES} bytes")
    found = detect(name, data)
    if found == "kmz":
        return "kml", kml.read(unzipped_kml(data), budget())
    if found == "kml":
        return "kml", kml.read(data.removeprefix(UTF8_BOM), budget())
    document = _json(data)
    if isinstance(document, dict) and document.get("type") == "FeatureCollection":
        if ed318.is_ed318(document):
            return "ed318", ed318.read(document, budget())
        return "geojson", geojson.read(document, budget())
    return "ed269", ed269.read(document, budget())


def bounding_box(shapes: list[dict]) -> dict[str, float]:
    lats: list[float] = []
    lons: list[float] = []
    for shape in shapes:
        if shape["type"] == "polygon":
            lats += [p[0] for p in shape["points"]]
            lons += [p[1] for p in shape["points"]]
        else:
            (lat, lon), radius = shape["center"], shape["radius"]
            dlat, dlon = _degrees(radius, lat)
            lats += [lat - dlat, lat + dlat]
            lons += [lon - dlon, lon + dlon]
    return {"min_lat": min(lats), "max_lat": max(lats), "min_lon": min(lons), "max_lon": max(lons)}


def _degrees(metres: float, lat: float) -> tuple[float, float]:
    """A distance as degrees of latitude and of longitude there (rounded up a little)."""
    north, east = ned_to_latlon(metres * 1.01, metres * 1.01, (lat, 0.0))
    return north - lat, min(abs(east), 180.0)


def _row(zone: ParsedZone, organisation: Any, source: str, file_format: str) -> Zone:
    return Zone(
        organisation=organisation,
        identifier=zone.identifier,
        part=zone.part,
        name=zone.name,
        restriction=zone.restriction,
        shapes=zone.shapes,
        lower_m=zone.band.lower_m,
        lower_ref=zone.band.lower_ref,
        upper_m=zone.band.upper_m,
        upper_ref=zone.band.upper_ref,
        applicability=zone.applicability,
        message=zone.message,
        source=source[:200],
        file_format=file_format,
        **bounding_box(zone.shapes),
    )


UPDATED_FIELDS = [
    "name",
    "restriction",
    "shapes",
    "lower_m",
    "lower_ref",
    "upper_m",
    "upper_ref",
    "applicability",
    "message",
    "source",
    "file_format",
    "min_lat",
    "min_lon",
    "max_lat",
    "max_lon",
    "imported_at",
]


def import_bytes(name: str, data: bytes, organisation: Any = None, source: str = "") -> Imported:
    """Read a zone file and store its zones for `organisation` (None: site-wide). A zone
    already known by identifier and part is updated in place, keeping its authorisations;
    parts the file no longer has are removed."""
    file_format, zones = parse(name, data)
    rows = [_row(z, organisation, source or Path(name).name, file_format) for z in zones]
    with transaction.atomic():
        scope = Zone.objects.select_for_update().filter(
            organisation=organisation, identifier__in={z.identifier for z in zones}
        )
        known = {(z.identifier, z.part): z for z in scope}
        for row in rows:
            row.pk = getattr(known.pop((row.identifier, row.part), None), "pk", None)
        updated = [row for row in rows if row.pk]
        Zone.objects.filter(pk__in=[z.pk for z in known.values()]).delete()
        Zone.objects.bulk_update(updated, UPDATED_FIELDS, batch_size=500)
        Zone.objects.bulk_create([row for row in rows if not row.pk], batch_size=500)
    return Imported(file_format, len(rows), len(updated))

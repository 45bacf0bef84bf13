"""Zone files in the forms publishers also use: EUROCAE ED-318 (the ED-269 successor;
examples from its schema's repository, tests/data/README.md), Google Earth's zipped KML,
and the rules every format shares."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import pytest

from zones.formats.common import ZoneFileError
from zones.store import parse

ED318 = Path(__file__).parents[1] / "data" / "zones" / "ed318"
FIXTURES = Path(__file__).parent / "fixtures"


def test_ed318_layers_become_parts_with_their_own_bands():
    file_format, zones = parse("zones.json", (ED318 / "Example_GeoZone_2_Layers.json").read_bytes())
    assert file_format == "ed318"
    assert [(z.identifier, z.part, z.restriction) for z in zones] == [
        ("NFZ6547", 0, "authorisation_required"),
        ("NFZ6547", 1, "authorisation_required"),
    ]
    assert [(z.band.lower_m, z.band.upper_m, z.band.lower_ref) for z in zones] == [
        (50.0, 150.0, "AGL"),
        (0.0, 50.0, "AGL"),
    ]
    assert zones[0].name == "LFPG-2"  # the English of its names
    assert zones[0].shapes[0]["points"][0] == [49.029301, 2.585866]  # [lat, lon]
    period = zones[0].applicability[0]
    assert period["start"] == "2018-12-31T15:59:59+00:00"
    assert period["schedule"][1] == {"days": ["SUN"], "start": "10:00", "end": "12:00"}


def test_an_ed318_point_with_a_circle_extent_is_a_circle_in_the_layers_unit():
    _, (zone,) = parse("circle.json", (ED318 / "Example_GeoZone_Circle.json").read_bytes())
    assert zone.restriction == "prohibited" and zone.applicability == []
    assert zone.shapes == [{"type": "circle", "center": [50.122901, 2.636866], "radius": 3500.0}]
    document = json.loads((ED318 / "Example_GeoZone_Circle.json").read_text())
    document["features"][0]["geometry"]["layer"]["uom"] = "ft"
    _, (in_feet,) = parse("circle.json", json.dumps(document).encode())
    assert in_feet.shapes[0]["radius"] == pytest.approx(3500 * 0.3048)
    assert in_feet.band.upper_m == pytest.approx(150 * 0.3048)


def test_an_ed318_collection_skips_what_restricts_nothing_and_reads_a_uspace_as_conditional():
    document = json.loads((ED318 / "Example_Collection.json").read_text())
    kinds = {f["properties"]["identifier"]: f["properties"]["type"] for f in document["features"]}
    first, second = list(kinds)[:2]
    document["features"][0]["properties"]["type"] = "NO_RESTRICTION"
    document["features"][1]["properties"]["type"] = "USPACE"
    _, zones = parse("collection.json", json.dumps(document).encode())
    assert first not in {z.identifier for z in zones}
    assert {z.restriction for z in zones if z.identifier == second} == {"conditional"}


def test_an_ed318_zone_without_its_layer_is_refused_naming_where():
    document = json.loads((ED318 / "Example_GeoZone_Circle.json").read_text())
    del document["features"][0]["geometry"]["layer"]
    with pytest.raises(ZoneFileError) as refused:
        parse("circle.json", json.dumps(document).encode())
    assert str(refused.value).startswith("features[0].geometry.layer: the altitude band is unknown")


def kmz(kml: bytes, name: str = "doc.kml") -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(name, kml)
        archive.writestr("files/icon.png", b"\x89PNG")
    return out.getvalue()


def test_a_kmz_reads_as_the_kml_inside_it_and_a_bom_does_not_hide_a_kml():
    kml = (FIXTURES / "reserve.kml").read_bytes()
    assert parse("reserve.kmz", kmz(kml)) == parse("reserve.kml", kml)
    assert parse("export.xml", b"\xef\xbb\xbf" + kml) == parse("reserve.kml", kml)


def test_a_kmz_is_held_to_the_size_limit_unzipped(settings):
    settings.ZONES_MAX_FILE_BYTES = 10_000
    bomb = kmz(b"<kml>" + b" " * 50_000 + b"</kml>")
    assert len(bomb) < 10_000
    with pytest.raises(ZoneFileError, match="larger than 10000 bytes unzipped"):
        parse("bomb.kmz", bomb)
    with pytest.raises(ZoneFileError, match="holds no .kml file"):
        parse("empty.kmz", kmz(b"x", name="readme.txt"))


def test_a_polygon_drawn_there_and_back_encloses_nothing_and_is_refused():
    document = json.loads((FIXTURES / "field.geojson").read_text())
    ring = document["features"][0]["geometry"]["coordinates"][0]
    a, b = ring[0], ring[1]
    document["features"][0]["geometry"]["coordinates"] = [[a, b, b, a, a]]
    with pytest.raises(ZoneFileError, match="at least 3 distinct points"):
        parse("field.geojson", json.dumps(document).encode())
    c = [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]
    document["features"][0]["geometry"]["coordinates"] = [[a, c, b, a]]
    with pytest.raises(ZoneFileError, match="encloses no area"):
        parse("field.geojson", json.dumps(document).encode())


@pytest.mark.django_db
def test_an_ed318_file_imports_by_command_into_stored_zones(tmp_path):
    from io import StringIO

    from django.core.management import call_command

    from zones.models import Zone

    out = StringIO()
    call_command("import_zones", str(ED318 / "Example_GeoZone_2_Layers.json"), stdout=out)
    assert "imported 2 zones (ed318" in out.getvalue()
    assert sorted(Zone.objects.values_list("identifier", "part", "upper_m")) == [
        ("NFZ6547", 0, 150.0),
        ("NFZ6547", 1, 50.0),
    ]

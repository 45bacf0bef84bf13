"""Zone files as publishers issue them: GeoJSON, EUROCAE ED-269 and KML imported through
`manage.py import_zones`; a malformed file is refused naming its problem and changes
nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from django.core.management import CommandError, call_command

from zones.formats.common import ZoneFileError
from zones.formats.kml import safe_tree
from zones.models import Zone
from zones.store import import_bytes

pytestmark = pytest.mark.django_db

FIXTURES = Path(__file__).parent / "fixtures"


def fixture(name: str) -> bytes:
    return (FIXTURES / name).read_bytes()


def import_file(path: Path, org: str | None = None) -> str:
    from io import StringIO

    out = StringIO()
    call_command("import_zones", str(path), *(["--org", org] if org else []), stdout=out)
    return out.getvalue()


def test_geojson_polygon_with_its_band(world):
    assert "imported 1 zones (geojson, site-wide" in import_file(FIXTURES / "field.geojson")
    zone = Zone.objects.get()
    assert (zone.identifier, zone.name, zone.restriction) == (
        "LPT-FIELD-1",
        "Test field",
        "prohibited",
    )
    assert (zone.lower_m, zone.lower_ref, zone.upper_m, zone.upper_ref) == (0, "AGL", 60, "AGL")
    assert zone.organisation is None and zone.applicability == []
    ring = zone.shapes[0]["points"]
    assert ring[0] == [40.6311983, -8.6580918] and len(ring) == 4  # [lat, lon], unclosed
    assert zone.min_lat == pytest.approx(40.6311983) and zone.max_lon == pytest.approx(-8.6569082)


def test_ed269_circle_in_feet_and_timed_polygon(world):
    assert "imported 2 zones (ed269, acme" in import_file(FIXTURES / "portugal.ed269.json", "acme")
    circle = Zone.objects.get(identifier="LPR-CIRCLE-1")
    assert circle.organisation == world.org and circle.restriction == "authorisation_required"
    assert circle.shapes == [
        {"type": "circle", "center": [40.6276051, -8.6527653], "radius": pytest.approx(152.4)}
    ]
    assert circle.upper_m == pytest.approx(121.92) and circle.upper_ref == "AGL"
    polygon = Zone.objects.get(identifier="LPR-POLY-2")
    assert polygon.upper_ref == "AMSL" and polygon.restriction == "prohibited"
    assert polygon.applicability == [
        {
            "start": "2026-01-01T00:00:00+00:00",
            "end": "2027-12-31T23:59:59+00:00",
            "schedule": [
                {"days": ["MON", "TUE", "WED", "THU", "FRI"], "start": "06:00", "end": "20:00"}
            ],
        }
    ]
    assert not Zone.objects.filter(identifier="LPR-INFO-3").exists()  # NO_RESTRICTION


def test_kml_placemark_with_its_band_in_extended_data(world):
    assert "imported 1 zones (kml" in import_file(FIXTURES / "reserve.kml")
    zone = Zone.objects.get()
    assert (zone.identifier, zone.name, zone.upper_m) == ("LPK-RESERVE-1", "Bird reserve", 100)
    assert zone.shapes[0]["points"][0] == [40.62, -8.64]


def test_a_new_edition_updates_zones_in_place(world):
    import_file(FIXTURES / "field.geojson")
    first = Zone.objects.get()
    edition = json.loads(fixture("field.geojson"))
    edition["features"][0]["properties"]["upperLimit"] = 90
    done = import_bytes("field.geojson", json.dumps(edition).encode())
    assert (done.zones, done.updated) == (1, 1)
    assert Zone.objects.get().pk == first.pk and Zone.objects.get().upper_m == 90


def with_feature(**changes: object) -> bytes:
    document = json.loads(fixture("field.geojson"))
    feature = document["features"][0]
    for key, value in changes.items():
        if key == "geometry":
            feature["geometry"] = value
        else:
            feature["properties"][key] = value
    second = json.loads(json.dumps(feature))
    second["properties"]["identifier"] = "LPT-FIELD-2"
    document["features"] = [json.loads(fixture("field.geojson"))["features"][0], second]
    return json.dumps(document).encode()


BOMB = b"""<?xml version="1.0"?>
<!DOCTYPE kml [
  <!ENTITY a "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa">
  <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
  <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">
  <!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">
]>
<kml xmlns="http://www.opengis.net/kml/2.2"><Document><Placemark><name>&d;</name>
</Placemark></Document></kml>"""

EXTERNAL = b"""<?xml version="1.0"?>
<!DOCTYPE kml [<!ENTITY x SYSTEM "file:///etc/passwd">]>
<kml xmlns="http://www.opengis.net/kml/2.2"><Document><name>&x;</name></Document></kml>"""


@pytest.mark.parametrize(
    ("name", "data", "words"),
    [
        ("bad.json", b'{"type": "FeatureCollection", "features": [', "not valid JSON"),
        ("bad.geojson", with_feature(uomDimensions="KM"), "unknown unit 'KM'"),
        ("bad.geojson", with_feature(upperVerticalReference="QNH"), "unknown vertical reference"),
        ("bad.geojson", with_feature(upperLimit=None), "altitude band is unknown"),
        (
            "bad.geojson",
            with_feature(
                geometry={
                    "type": "Polygon",
                    "coordinates": [
                        [[-8.65, 40.63], [-8.64, 40.64], [-8.65, 40.64], [-8.64, 40.63]]
                    ],
                }
            ),
            "must not intersect itself",
        ),
        (
            "bad.geojson",
            with_feature(geometry={"type": "Point", "coordinates": [-8.65, 40.63]}),
            "must be Polygon or MultiPolygon",
        ),
        ("bad.geojson", with_feature(restriction="FORBIDDEN"), "unknown restriction"),
        ("bomb.kml", BOMB, "document type declarations and entities are refused"),
        ("external.kml", EXTERNAL, "document type declarations and entities are refused"),
        ("broken.kml", b"<kml><Placemark>", "not well-formed XML"),
    ],
    ids=[
        "json",
        "units",
        "reference",
        "band",
        "self-intersecting",
        "point",
        "restriction",
        "entity-bomb",
        "external-entity",
        "xml",
    ],
)
def test_a_malformed_file_is_refused_and_nothing_changes(world, tmp_path, name, data, words):
    import_file(FIXTURES / "field.geojson")
    before = list(Zone.objects.values())
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(CommandError) as refused:
        import_file(path)
    assert words in str(refused.value) and "nothing imported" in str(refused.value)
    assert list(Zone.objects.values()) == before


def test_a_kml_placemark_without_a_band_is_refused(world):
    kml = fixture("reserve.kml").replace(b'<Data name="upperLimit"><value>100</value></Data>', b"")
    with pytest.raises(ZoneFileError) as refused:
        import_bytes("reserve.kml", kml)
    assert "altitude band is unknown: no upperLimit" in str(refused.value)
    assert not Zone.objects.exists()


def test_the_entity_guard_leaves_a_plain_document_alone():
    assert safe_tree(fixture("reserve.kml")).tag.endswith("kml")


def test_an_oversized_file_is_refused_before_reading(world, settings, tmp_path):
    settings.ZONES_MAX_FILE_BYTES = 100
    with pytest.raises(CommandError, match="larger than 100 bytes"):
        import_file(FIXTURES / "field.geojson")
    assert not Zone.objects.exists()


def test_too_many_vertices_are_refused(world, settings):
    settings.ZONES_MAX_VERTICES = 3
    with pytest.raises(ZoneFileError, match="more than 3 vertices"):
        import_bytes("field.geojson", fixture("field.geojson"))
    assert not Zone.objects.exists()


def test_an_unknown_organisation_is_refused(world):
    with pytest.raises(CommandError, match="Unknown organisation"):
        import_file(FIXTURES / "field.geojson", "nowhere")


def admin_upload(client, name: str, data: bytes, **fields):  # type: ignore[no-untyped-def]
    from django.core.files.uploadedfile import SimpleUploadedFile

    body = {"file": SimpleUploadedFile(name, data), **fields}
    return client.post("/admin/zones/zone/import/", body)


def test_the_admin_upload_is_for_staff_who_may_add_zones(world, client, settings):
    from django.contrib.auth import get_user_model

    client.force_login(world.owner)  # an organisation's admin, not staff
    response = admin_upload(client, "field.geojson", fixture("field.geojson"))
    assert response.status_code == 302 and "/login/" in response["Location"]
    staff = get_user_model().objects.create_user("clerk", password="pw-for-tests-2", is_staff=True)
    client.force_login(staff)
    assert admin_upload(client, "field.geojson", fixture("field.geojson")).status_code == 403
    assert not Zone.objects.exists()

    client.force_login(get_user_model().objects.create_superuser("root", password="pw-3-x"))
    response = admin_upload(client, "portugal.ed269.json", fixture("portugal.ed269.json"))
    assert response.status_code == 302, response.content[:2000]
    assert set(Zone.objects.values_list("organisation", flat=True)) == {None}
    response = admin_upload(
        client, "portugal.ed269.json", fixture("portugal.ed269.json"), organisation=world.org.pk
    )
    assert response.status_code == 302, response.content[:2000]
    assert Zone.objects.filter(organisation=world.org).count() == 2
    assert Zone.objects.filter(organisation=None).count() == 2


def test_the_admin_refuses_a_malformed_or_oversized_upload(world, client, settings):
    from django.contrib.auth import get_user_model

    client.force_login(get_user_model().objects.create_superuser("root", password="pw-4-x"))
    response = admin_upload(client, "bomb.kml", BOMB)
    assert response.status_code == 200
    assert b"Refused, nothing imported" in response.content
    assert b"document type declarations and entities are refused" in response.content
    settings.ZONES_MAX_FILE_BYTES = 100
    response = admin_upload(client, "field.geojson", fixture("field.geojson"))
    assert response.status_code == 200 and b"Larger than 100 bytes" in response.content
    assert not Zone.objects.exists()


def test_the_admin_shows_zones_without_editing_them(world, client):
    from django.contrib.auth import get_user_model

    client.force_login(get_user_model().objects.create_superuser("root", password="pw-5-x"))
    import_file(FIXTURES / "field.geojson")
    zone = Zone.objects.get()
    assert client.get("/admin/zones/zone/").status_code == 200
    assert client.get("/admin/zones/zone/add/")["Location"] == "/admin/zones/zone/import/"
    client.post(f"/admin/zones/zone/{zone.pk}/change/", {"name": "Renamed", "upper_m": 5})
    assert Zone.objects.get().name == "Test field" and Zone.objects.get().upper_m == 60

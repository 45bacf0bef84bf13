"""`GET /api/v1/zones/`: the zones of the user's organisations and the site-wide ones, as
an RFC 7946 FeatureCollection, within a bounding box when asked."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.missions.test_envelope import client_for
from zones.models import Zone
from zones.store import import_bytes

pytestmark = pytest.mark.django_db

FIXTURES = Path(__file__).parent / "fixtures"


def imported(name: str, organisation=None) -> None:  # type: ignore[no-untyped-def]
    import_bytes(name, (FIXTURES / name).read_bytes(), organisation)


def identifiers(body: dict) -> list[str]:
    return sorted(f["properties"]["identifier"] for f in body["features"])


def test_each_user_sees_their_organisations_zones_and_the_site_wide_ones(world):
    imported("field.geojson")
    imported("portugal.ed269.json", world.org)
    imported("reserve.kml", world.other_org)
    mine = client_for(world.viewer).get("/api/v1/zones/").json()
    assert identifiers(mine) == ["LPR-CIRCLE-1", "LPR-POLY-2", "LPT-FIELD-1"]
    theirs = client_for(world.outsider).get("/api/v1/zones/").json()
    assert identifiers(theirs) == ["LPK-RESERVE-1", "LPT-FIELD-1"]
    assert client_for(None).get("/api/v1/zones/").status_code == 401
    other = Zone.objects.get(identifier="LPK-RESERVE-1").pk
    assert client_for(world.viewer).get(f"/api/v1/zones/{other}/authorisations/").status_code == 404


def test_features_are_geojson_with_the_band_and_the_exact_circle(world):
    imported("portugal.ed269.json", world.org)
    body = client_for(world.viewer).get("/api/v1/zones/").json()
    assert body["type"] == "FeatureCollection" and body["truncated"] is False
    circle = next(f for f in body["features"] if f["properties"]["identifier"] == "LPR-CIRCLE-1")
    assert circle["geometry"]["type"] == "MultiPolygon"
    ring = circle["geometry"]["coordinates"][0][0]
    assert ring[0] == ring[-1] and len(ring) == 65  # closed, [lon, lat]
    assert all(-8.66 < lon < -8.64 and 40.62 < lat < 40.64 for lon, lat in ring)
    props = circle["properties"]
    assert props["circles"] == [
        {"center": [-8.6527653, 40.6276051], "radius": pytest.approx(152.4)}
    ]
    assert props["restriction"] == "authorisation_required" and props["organisation"] == "acme"
    assert props["band"].startswith("0 m AGL – 121.92 m AGL")
    assert props["applicability_text"] == "permanent" and props["applies_now"] is True


def test_a_bounding_box_narrows_the_list_and_a_bad_one_is_refused(world, settings):
    imported("field.geojson")
    imported("reserve.kml")
    client = client_for(world.viewer)
    near_field = client.get("/api/v1/zones/?bbox=-8.659,40.631,-8.656,40.633").json()
    assert identifiers(near_field) == ["LPT-FIELD-1"]
    response = client.get("/api/v1/zones/?bbox=west,1,2,3")
    assert response.status_code == 400 and "bbox" in response.json()["fields"]
    settings.ZONES_LIST_LIMIT = 1
    assert client.get("/api/v1/zones/").json()["truncated"] is True


def test_a_token_bound_to_one_organisation_sees_its_zones_only(world):
    from rest_framework.test import APIClient

    from accounts import tokens
    from fleet.models import Membership, Role

    Membership.objects.create(user=world.operator, organisation=world.other_org, role=Role.VIEWER)
    imported("field.geojson")
    imported("portugal.ed269.json", world.org)
    imported("reserve.kml", world.other_org)
    everything = client_for(world.operator).get("/api/v1/zones/").json()
    assert "LPK-RESERVE-1" in identifiers(everything)
    issued = tokens.issue(world.operator, name="acme only", organisation=world.org, days=1)
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Token {issued.key}")
    bound = client.get("/api/v1/zones/").json()
    assert identifiers(bound) == ["LPR-CIRCLE-1", "LPR-POLY-2", "LPT-FIELD-1"]

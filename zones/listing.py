"""Zones as the API and the maps show them: an RFC 7946 FeatureCollection.

Circles have no GeoJSON geometry: each is drawn as a ring of CIRCLE_SEGMENTS points and
given exactly in the feature's `circles` property ([longitude, latitude], radius in m).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from datetime import datetime
from typing import Any

from django.db.models import Q, QuerySet

from fleet.models import Membership
from onboard.envelope import ned_to_latlon

from .bands import Band
from .models import Zone
from .windows import applies_at, describe

CIRCLE_SEGMENTS = 64


def visible_to(user: Any) -> QuerySet[Zone]:
    """The zones of the user's organisations (a token bound to one: that one) and the
    site-wide ones."""
    mine = Membership.objects.for_user(user).values("organisation_id")
    return Zone.objects.filter(Q(organisation_id__in=mine) | Q(organisation__isnull=True))


def in_box(zones: QuerySet[Zone], box: tuple[float, float, float, float]) -> QuerySet[Zone]:
    """The zones whose bounding box meets (west, south, east, north)."""
    west, south, east, north = box
    return zones.filter(
        min_lat__lte=north, max_lat__gte=south, min_lon__lte=east, max_lon__gte=west
    )


def _ring(shape: dict) -> list[list[float]]:
    if shape["type"] == "polygon":
        points = [[lon, lat] for lat, lon in shape["points"]]
    else:
        center, radius = shape["center"], shape["radius"]
        points = []
        for k in range(CIRCLE_SEGMENTS):
            angle = 2 * math.pi * k / CIRCLE_SEGMENTS
            lat, lon = ned_to_latlon(radius * math.cos(angle), radius * math.sin(angle), center)
            points.append([round(lon, 7), round(lat, 7)])
    return [*points, points[0]]


def feature(zone: Zone, now: datetime) -> dict:
    band = Band(zone.lower_m, zone.lower_ref, zone.upper_m, zone.upper_ref)
    circles = [
        {"center": [s["center"][1], s["center"][0]], "radius": s["radius"]}
        for s in zone.shapes
        if s["type"] == "circle"
    ]
    return {
        "type": "Feature",
        "id": zone.pk,
        "geometry": {
            "type": "MultiPolygon",
            "coordinates": [[_ring(shape)] for shape in zone.shapes],
        },
        "properties": {
            "identifier": zone.identifier,
            "part": zone.part,
            "name": zone.name,
            "restriction": zone.restriction,
            "lowerLimit": zone.lower_m,
            "lowerVerticalReference": zone.lower_ref,
            "upperLimit": zone.upper_m,
            "upperVerticalReference": zone.upper_ref,
            "uomDimensions": "M",
            "band": band.text(),
            "applicability": zone.applicability,
            "applicability_text": describe(zone.applicability),
            "applies_now": applies_at(zone.applicability, now),
            "message": zone.message,
            "source": zone.source,
            "organisation": zone.organisation.slug if zone.organisation_id else None,
            "circles": circles,
        },
    }


def collection(zones: Iterable[Zone], now: datetime, truncated: bool) -> dict:
    return {
        "type": "FeatureCollection",
        "features": [feature(z, now) for z in zones],
        "truncated": truncated,
    }

"""REST resources of the published zones.

`GET /api/v1/zones/` lists the zones the user may see (their organisations' and the
site-wide ones) as a GeoJSON FeatureCollection, optionally within `bbox`;
`GET/POST /api/v1/zones/{id}/authorisations/` lists and records authorisations.
"""

from __future__ import annotations

import math

from django.conf import settings
from django.utils import timezone
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import exceptions, serializers, status
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from config.api import StrictSerializer

from . import authorisations, listing
from .models import Zone


def parse_bbox(raw: str | None) -> tuple[float, float, float, float] | None:
    """`west,south,east,north` in degrees (RFC 7946 §5 order), or None when absent."""
    if not raw:
        return None
    try:
        values = tuple(float(v) for v in raw.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise exceptions.ValidationError({"bbox": ["must be west,south,east,north in degrees"]})
    return values  # type: ignore[return-value]


class ZoneListView(APIView):
    """`GET /api/v1/zones/`: at most ZONES_LIST_LIMIT zones (`truncated` says when more
    matched: ask for a smaller `bbox`)."""

    @extend_schema(
        parameters=[OpenApiParameter("bbox", str, description="west,south,east,north")],
        responses={200: OpenApiTypes.OBJECT},
    )
    def get(self, request: Request) -> Response:
        zones = listing.visible_to(request.user).select_related("organisation")
        box = parse_bbox(request.query_params.get("bbox"))
        if box is not None:
            zones = listing.in_box(zones, box)
        limit = settings.ZONES_LIST_LIMIT
        found = list(zones[: limit + 1])
        return Response(listing.collection(found[:limit], timezone.now(), len(found) > limit))


class AuthorisationSerializer(StrictSerializer):
    issued_by = serializers.CharField(max_length=200)
    reference = serializers.CharField(max_length=200)
    expires_at = serializers.DateTimeField()
    organisation = serializers.SlugField(required=False)


def _zone(request: Request, pk: int) -> Zone:
    zone = listing.visible_to(request.user).filter(pk=pk).first()
    if zone is None:
        raise exceptions.NotFound(f"Unknown zone {pk}.")
    return zone


class Conflict(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "conflict"


def _refusal(exc: authorisations.AuthorisationRefused) -> exceptions.APIException:
    if exc.status == 400:
        return exceptions.ValidationError({exc.field or "non_field_errors": [exc.message]})
    if exc.status == 403:
        return exceptions.PermissionDenied(exc.message)
    return Conflict(exc.message)


class AuthorisationView(APIView):
    """`GET/POST /api/v1/zones/{id}/authorisations/`: the authorisations the user's
    organisations hold for the zone; an organisation's admin records a new one (who issued
    it, its reference, its expiry)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, pk: int) -> Response:
        now = timezone.now()
        found = authorisations.of_zone(request.user, _zone(request, pk))
        return Response({"authorisations": [authorisations.as_dict(a, now) for a in found]})

    @extend_schema(request=AuthorisationSerializer, responses={201: OpenApiTypes.OBJECT})
    def post(self, request: Request, pk: int) -> Response:
        zone = _zone(request, pk)
        body = AuthorisationSerializer(data=request.data)
        body.is_valid(raise_exception=True)
        try:
            made = authorisations.record(request.user, zone, **body.validated_data)
        except authorisations.AuthorisationRefused as exc:
            raise _refusal(exc) from None
        return Response(authorisations.as_dict(made), status=status.HTTP_201_CREATED)

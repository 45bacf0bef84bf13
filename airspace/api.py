"""`GET /api/v1/organisations/{slug}/reservations/`: the airspace an organisation's
flights hold now."""

from __future__ import annotations

from drf_spectacular.utils import extend_schema
from rest_framework import serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

# The organisation when the user (or the token's one organisation) is a member, else 404.
from fleet.api import _member_organisation

from . import listing


class LegSerializer(serializers.Serializer):
    start = serializers.ListField(child=serializers.FloatField(), help_text="[lat, lon]")
    end = serializers.ListField(child=serializers.FloatField(), help_text="[lat, lon]")
    radius_m = serializers.FloatField(help_text="The corridor's horizontal radius.")
    band_m = serializers.ListField(
        child=serializers.FloatField(), help_text="[lowest, highest] metres above home"
    )
    window = serializers.ListField(child=serializers.DateTimeField(), help_text="[from, to]")


class ReservationSerializer(serializers.Serializer):
    id = serializers.IntegerField()
    drone_id = serializers.CharField()
    kind = serializers.ChoiceField(choices=["mission", "command"])
    mission_id = serializers.UUIDField(allow_null=True)
    command = serializers.CharField(allow_blank=True)
    window = serializers.ListField(child=serializers.DateTimeField(), help_text="[from, to]")
    separation_m = serializers.DictField(
        child=serializers.FloatField(), help_text="{horizontal, vertical} minima it keeps"
    )
    legs = LegSerializer(many=True)


class ReservationsSerializer(serializers.Serializer):
    organisation = serializers.CharField()
    separation_m = serializers.DictField(child=serializers.FloatField())
    reservations = ReservationSerializer(many=True)


class ReservationsView(APIView):
    """The organisation's active reservations: each drone's corridors (segment, radius,
    altitude band) and time windows. Every member reads them; other organisations'
    reservations are never listed."""

    @extend_schema(responses={200: ReservationsSerializer})
    def get(self, request: Request, slug: str) -> Response:
        return Response(listing.reservations_body(_member_organisation(request, slug)))

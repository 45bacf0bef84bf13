"""The trends of the log checks' figures over the API: the fleet's for one check, and one
drone's for every check (`/api/v1/logs/trends/`); the statistic is logs/trends.py's."""

from __future__ import annotations

from django.conf import settings
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema, inline_serializer
from rest_framework import exceptions, serializers
from rest_framework.permissions import IsAuthenticated
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from fleet.models import Drone, Organisation
from logs import trends
from logs.api import chosen_membership
from logs.checks import CHECKS

DEFAULT_CHECK = "vibration"


def statistic() -> dict:
    return {
        "history": int(settings.LOGS_TREND_HISTORY),
        "min_history": int(settings.LOGS_TREND_MIN_HISTORY),
        "sigmas": float(settings.LOGS_TREND_SIGMAS),
        "fleet_min_drones": trends.FLEET_MIN_DRONES,
        "rule": "newest figure beyond mean ± sigmas·(sample standard deviation) of the "
        "drone's previous `history` flights, or of the other drones' latest `history` "
        "flights pooled, on the worse side",
    }


def check_named(raw: str | None) -> str:
    check = raw or DEFAULT_CHECK
    if check not in CHECKS:
        raise exceptions.ValidationError({"check": [f"One of: {', '.join(CHECKS)}."]})
    return check


def organisation_of(request: Request) -> Organisation:
    """`?organisation=<slug>`, else the one the portal acts for, else the only membership."""
    return chosen_membership(request, request.query_params.get("organisation") or "").organisation


POINT = inline_serializer(
    "LogTrendPoint",
    {
        "log": serializers.UUIDField(),
        "at": serializers.DateTimeField(),
        "value": serializers.FloatField(),
        "unit": serializers.CharField(),
        "status": serializers.CharField(),
    },
)
DRIFT = inline_serializer(
    "LogTrendDrift",
    {
        "basis": serializers.ChoiceField(["own", "fleet"]),
        "value": serializers.FloatField(),
        "mean": serializers.FloatField(),
        "std": serializers.FloatField(),
        "limit": serializers.FloatField(),
        "n": serializers.IntegerField(),
        "sigmas": serializers.FloatField(),
    },
)
TREND = {"points": serializers.ListField(child=POINT), "drift": serializers.ListField(child=DRIFT)}


class FleetTrend(APIView):
    permission_classes = [IsAuthenticated]

    @extend_schema(
        parameters=[
            OpenApiParameter("check", OpenApiTypes.STR, description="A check's name (vibration)."),
            OpenApiParameter("organisation", OpenApiTypes.STR, description="Its slug."),
        ],
        responses=inline_serializer(
            "LogFleetTrend",
            {
                "check": serializers.CharField(),
                "statistic": serializers.DictField(),
                "drones": serializers.ListField(
                    child=inline_serializer(
                        "LogDroneFigures", {"drone": serializers.CharField(), **TREND}
                    )
                ),
            },
        ),
    )
    def get(self, request: Request) -> Response:
        """One check's figure over every drone's logs, each drone's newest judged against
        its own history and the fleet."""
        check = check_named(request.query_params.get("check"))
        organisation = organisation_of(request)
        return Response(
            {
                "check": check,
                "statistic": statistic(),
                "drones": trends.fleet_trend(organisation, check),
            }
        )


class DroneTrend(APIView):
    permission_classes = [IsAuthenticated]

    @extend_schema(
        responses=inline_serializer(
            "LogDroneTrend",
            {
                "drone": serializers.CharField(),
                "statistic": serializers.DictField(),
                "checks": serializers.DictField(child=inline_serializer("LogCheckTrend", TREND)),
            },
        )
    )
    def get(self, request: Request, drone_id: str) -> Response:
        """Every check's figure over the drone's logs, the newest judged."""
        drone = Drone.objects.for_user(request.user).filter(drone_id=drone_id).first()
        if drone is None:
            raise exceptions.NotFound("There is no such drone among yours.")
        return Response(
            {
                "drone": drone.drone_id,
                "statistic": statistic(),
                "checks": trends.drone_trend(drone, CHECKS),
            }
        )

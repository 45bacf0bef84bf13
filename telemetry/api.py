"""`/api/v1/telemetry/…`: latest values, downsampled ranges, CSV export and ingest status.

Every endpoint resolves the drone through `Drone.objects.for_user`, so a drone of another
organisation answers 404 exactly like one that does not exist.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from django.http import StreamingHttpResponse
from django.shortcuts import get_object_or_404
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import (
    OpenApiParameter,
    extend_schema,
    extend_schema_field,
    inline_serializer,
)
from rest_framework import serializers
from rest_framework.decorators import api_view
from rest_framework.request import Request
from rest_framework.response import Response

from config.api import StrictSerializer
from fleet.models import DRONE_ID_RE, Drone
from onboard.protocol import OBJECT_NAME_RE
from workers import ingest_status as status

from . import queries

MAX_RANGE = timedelta(days=400)


@extend_schema_field(OpenApiTypes.STR)
class EpochOrIsoField(serializers.Field):
    """A time as epoch seconds or ISO 8601 (UTC unless it says otherwise)."""

    default_error_messages = {"invalid": "Give epoch seconds or an ISO 8601 time."}

    def to_internal_value(self, data: object) -> datetime:
        try:
            return datetime.fromtimestamp(float(data), UTC)  # type: ignore[arg-type]
        except (TypeError, ValueError, OverflowError, OSError):
            pass
        try:
            value = datetime.fromisoformat(str(data).replace("Z", "+00:00"))
        except ValueError:
            self.fail("invalid")
        return value if value.tzinfo else value.replace(tzinfo=UTC)

    def to_representation(self, value: datetime) -> float:
        return value.timestamp()


def _names(value: str, what: str) -> list[str]:
    names = [part.strip() for part in value.split(",") if part.strip()]
    bad = [n for n in names if not OBJECT_NAME_RE.match(n)]
    if bad:
        raise serializers.ValidationError(f"{bad[0]!r} is not a {what} name.")
    return names


class RangeQuery(StrictSerializer):
    object = serializers.RegexField(OBJECT_NAME_RE.pattern)
    fields = serializers.CharField(help_text="Comma-separated field names.")
    start = EpochOrIsoField()
    end = EpochOrIsoField()
    points = serializers.IntegerField(min_value=1, max_value=10_000, default=1000)
    source = serializers.ChoiceField(["raw", "1s", "1m"], required=False)

    def validate_fields(self, value: str) -> list[str]:
        names = _names(value, "field")
        if not names or len(names) > 16:
            raise serializers.ValidationError("Give between 1 and 16 field names.")
        return names

    def validate(self, attrs: dict) -> dict:
        if attrs["end"] <= attrs["start"]:
            raise serializers.ValidationError({"end": ["Must be after start."]})
        if attrs["end"] - attrs["start"] > MAX_RANGE:
            raise serializers.ValidationError({"end": ["The range is longer than 400 days."]})
        return attrs


class ExportQuery(StrictSerializer):
    object = serializers.RegexField(OBJECT_NAME_RE.pattern, required=False)
    fields = serializers.CharField(required=False, help_text="Comma-separated field names.")
    start = EpochOrIsoField()
    end = EpochOrIsoField()
    layout = serializers.ChoiceField(
        ["wide", "long"],
        default="wide",
        help_text="wide: one column per field (default); long: ts, object, fields as JSON.",
    )

    def validate_fields(self, value: str) -> list[str]:
        return _names(value, "field")

    def validate(self, attrs: dict) -> dict:
        if attrs["end"] <= attrs["start"]:
            raise serializers.ValidationError({"end": ["Must be after start."]})
        if attrs.get("fields") and attrs.get("layout") == "long":
            raise serializers.ValidationError({"fields": ["Field columns need layout=wide."]})
        if attrs.get("fields") and not attrs.get("object"):
            raise serializers.ValidationError({"fields": ["Choose an object to pick fields of."]})
        return attrs


def _drone(request: Request, drone_id: str) -> Drone:
    if not DRONE_ID_RE.match(drone_id):
        raise serializers.ValidationError({"drone_id": ["Not a drone id."]})
    return get_object_or_404(Drone.objects.for_user(request.user), drone_id=drone_id)


SampleOut = inline_serializer(
    "TelemetrySample", {"ts": serializers.FloatField(), "fields": serializers.DictField()}
)


@extend_schema(
    summary="Latest value of every object a drone has sent",
    parameters=[OpenApiParameter("objects", OpenApiTypes.STR, description="Comma-separated.")],
    responses=inline_serializer(
        "TelemetryLatest",
        {"drone_id": serializers.CharField(), "objects": serializers.DictField(child=SampleOut)},
    ),
)
@api_view(["GET"])
def latest(request: Request, drone_id: str) -> Response:
    drone = _drone(request, drone_id)
    wanted = request.query_params.get("objects")
    try:
        names = _names(wanted, "object") if wanted else None
    except serializers.ValidationError as exc:
        raise serializers.ValidationError({"objects": exc.detail}) from None
    return Response({"drone_id": drone.drone_id, "objects": queries.latest(drone.pk, names)})


@extend_schema(
    summary="A time range of chosen fields, downsampled to at most `points` buckets",
    parameters=[RangeQuery],
    responses=inline_serializer(
        "TelemetryRange",
        {
            "object": serializers.CharField(),
            "start": serializers.FloatField(),
            "end": serializers.FloatField(),
            "bucket_s": serializers.FloatField(),
            "source": serializers.ChoiceField(["raw", "1s", "1m"]),
            "t": serializers.ListField(child=serializers.FloatField()),
            "count": serializers.ListField(child=serializers.IntegerField()),
            "series": serializers.DictField(
                child=inline_serializer(
                    "TelemetrySeries",
                    {
                        "min": serializers.ListField(child=serializers.FloatField()),
                        "max": serializers.ListField(child=serializers.FloatField()),
                        "avg": serializers.ListField(child=serializers.FloatField()),
                    },
                )
            ),
        },
    ),
)
@api_view(["GET"])
def range_(request: Request, drone_id: str) -> Response:
    drone = _drone(request, drone_id)
    query = RangeQuery(data=request.query_params.dict())
    query.is_valid(raise_exception=True)
    q = query.validated_data
    result = queries.query_range(
        drone.pk, q["object"], q["fields"], q["start"], q["end"], q["points"], q.get("source")
    )
    return Response(result.to_dict())


@extend_schema(
    summary="CSV of every sample in a range (streamed)",
    parameters=[ExportQuery],
    responses={(200, "text/csv"): OpenApiTypes.STR},
)
@api_view(["GET"])
def export(request: Request, drone_id: str) -> StreamingHttpResponse:
    drone = _drone(request, drone_id)
    query = ExportQuery(data=request.query_params.dict())
    query.is_valid(raise_exception=True)
    q = query.validated_data
    rows = queries.export_csv(
        queries.conninfo_from_settings(),
        drone.pk,
        q["start"],
        q["end"],
        q.get("object"),
        q.get("fields") or (),
        layout=q["layout"],
    )
    response = StreamingHttpResponse(rows, content_type="text/csv; charset=utf-8")
    stamp = q["start"].strftime("%Y%m%dT%H%M%S")
    response["Content-Disposition"] = (
        f'attachment; filename="{drone.drone_id}-{q.get("object") or "all"}-{stamp}.csv"'
    )
    return response


@extend_schema(
    summary="Ingest process counters: rate, lag, stored, dropped by reason, overflow",
    responses=inline_serializer("TelemetryIngestStatus", {"processes": serializers.DictField()}),
)
@api_view(["GET"])
def ingest_status(request: Request) -> Response:
    return Response(status.ingest_status())

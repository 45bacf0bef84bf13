"""REST: flight records of the user's organisations (read by every member), and
corrections (organisation admins). Nothing here updates or deletes a record."""

from __future__ import annotations

from typing import Any

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import exceptions, serializers, status, viewsets
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response

from config.api import StrictSerializer
from fleet.models import Role
from fleet.permissions import require_role
from logs.collection import logs_of_flight

from . import corrections, logbook
from .models import FlightRecord


class Conflict(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "conflict"
    default_detail = "Conflict."


class FlightSerializer(serializers.ModelSerializer):
    drone = serializers.CharField(source="drone_ident")
    pilot = serializers.CharField(source="pilot_name", allow_blank=True)
    mission = serializers.UUIDField(source="mission_id", allow_null=True)
    corrected_by = serializers.SerializerMethodField()

    class Meta:
        model = FlightRecord
        fields = [
            "id", "drone", "origin", "pilot", "mission", "mission_name", "assignment_id",
            "started_at", "ended_at", "takeoff_at", "landing_at", "takeoff_position",
            "landing_position", "duration_s", "airborne_s", "distance_m", "max_height_m",
            "max_speed_ms", "max_distance_m", "battery_start", "battery_end", "voltage_start",
            "voltage_end", "energy_wh", "energy_method", "battery", "events", "corrects",
            "corrected_by", "correction_reason", "recorded_at",
        ]  # fmt: skip

    def get_corrected_by(self, record: FlightRecord) -> int | None:
        following = getattr(record, "corrected_by", None)
        return following.pk if following is not None else None


class FlightDetailSerializer(FlightSerializer):
    logs = serializers.SerializerMethodField(
        help_text="The logs the drone uploaded by itself for this flight (onboard recording, "
        "flight controller's log), each with its FlightLog id and checks."
    )

    class Meta(FlightSerializer.Meta):
        fields = [*FlightSerializer.Meta.fields, "track", "home", "samples", "logs"]

    def get_logs(self, record: FlightRecord) -> list[dict]:
        return [
            {
                "id": str(row.log_id),
                "kind": row.kind,
                "name": row.name,
                "format": row.log.format,
                "status": row.log.status,
                "url": row.log.get_absolute_url(),
                "checks": f"/api/v1/logs/{row.log_id}/checks/",
            }
            for row in logs_of_flight(record.drone_id, record.started_at, record.ended_at)
        ]


class CorrectionSerializer(StrictSerializer):
    reason = serializers.CharField(max_length=500)
    pilot = serializers.CharField(required=False, allow_blank=True, max_length=150)
    battery = serializers.CharField(required=False, allow_null=True, max_length=64)
    takeoff_at = serializers.DateTimeField(required=False, allow_null=True)
    landing_at = serializers.DateTimeField(required=False, allow_null=True)
    duration_s = serializers.FloatField(required=False, min_value=0, max_value=7 * 86400)
    airborne_s = serializers.FloatField(
        required=False, allow_null=True, min_value=0, max_value=7 * 86400
    )
    distance_m = serializers.FloatField(required=False, allow_null=True, min_value=0, max_value=1e7)
    max_height_m = serializers.FloatField(
        required=False, allow_null=True, min_value=-1e4, max_value=1e5
    )
    max_speed_ms = serializers.FloatField(
        required=False, allow_null=True, min_value=0, max_value=1e3
    )
    max_distance_m = serializers.FloatField(
        required=False, allow_null=True, min_value=0, max_value=1e7
    )
    battery_start = serializers.FloatField(
        required=False, allow_null=True, min_value=0, max_value=1
    )
    battery_end = serializers.FloatField(required=False, allow_null=True, min_value=0, max_value=1)
    energy_wh = serializers.FloatField(required=False, allow_null=True, min_value=0, max_value=1e6)


FILTER_PARAMETERS = [
    OpenApiParameter("drone", str, description="drone id"),
    OpenApiParameter("pilot", str, description="the pilot's username"),
    OpenApiParameter("mission", OpenApiTypes.UUID, description="mission id"),
    OpenApiParameter("since", str, description="started on or after (date or date-time)"),
    OpenApiParameter("until", str, description="started on or before (date or date-time)"),
    OpenApiParameter(
        "all", bool, description="true: every version, corrected ones too (default: current)"
    ),
]


class FlightViewSet(viewsets.ReadOnlyModelViewSet):
    """Flights of the organisations the user belongs to, newest first; others answer 404.
    By default only each flight's current version (corrections replace what they correct)."""

    def get_queryset(self):  # type: ignore[no-untyped-def]
        records = FlightRecord.objects.for_user(self.request.user).select_related("corrected_by")
        if self.action == "list":
            if self.request.query_params.get("all") not in ("1", "true"):
                records = records.current()
            try:
                records = logbook.filtered(records, self.request.query_params)
            except logbook.BadFilter as exc:
                raise exceptions.ValidationError({exc.field: [exc.message]}) from None
        return records

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        if self.action == "corrections":
            return CorrectionSerializer
        return FlightDetailSerializer if self.action == "retrieve" else FlightSerializer

    @extend_schema(parameters=FILTER_PARAMETERS)
    def list(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        return super().list(request, *args, **kwargs)

    @extend_schema(request=CorrectionSerializer, responses={201: FlightDetailSerializer})
    @action(detail=True, methods=["post"])
    def corrections(self, request: Request, pk: str | None = None) -> Response:
        """Correct the record: a new record naming this one (`corrects`); admins only."""
        record = self.get_object()
        if not require_role(request.user, record.organisation, Role.ADMIN):
            raise exceptions.PermissionDenied("Only organisation admins may correct records.")
        body = CorrectionSerializer(data=request.data)
        body.is_valid(raise_exception=True)
        changes = dict(body.validated_data)
        reason = changes.pop("reason")
        try:
            if "pilot" in changes:
                name = changes["pilot"]
                changes["pilot"] = (
                    corrections.pilot_in(record.organisation_id, name) if name else None
                )
            created = corrections.correct(record, changes, reason=reason, user=request.user)
        except corrections.CorrectionRefused as exc:
            if exc.status == status.HTTP_409_CONFLICT:
                raise Conflict(exc.message) from None
            raise exceptions.ValidationError({exc.field or "error": [exc.message]}) from None
        return Response(FlightDetailSerializer(created).data, status=status.HTTP_201_CREATED)

"""The log resource's comparison actions: parameters and their differences (with another
log, or with the organisation's reference set for the log's drone model), the two logs'
take-off times for one time axis, and which drone flew a log (its trends)."""

from __future__ import annotations

import uuid

from django.db import transaction
from django.utils import timezone
from django.utils.dateparse import parse_datetime
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema, inline_serializer
from rest_framework import exceptions, serializers, status
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response

from fleet.models import Drone, Role
from fleet.tenancy import role_in
from logs import compare, trends
from logs.models import FlightLog, ParameterReference
from logs.parameters import ParameterSet, diff, read_parameters

REFERENCE = "reference"
PARAMETER_SOURCES = "PX4 parameters, ArduPilot PARM, MAVLink PARAM_VALUE or dRonin settings objects"


class NoParameters(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "no_parameters"


def _query(name: str, text: str) -> OpenApiParameter:
    return OpenApiParameter(name, OpenApiTypes.STR, OpenApiParameter.QUERY, description=text)


PARAMETER_SET = inline_serializer(
    "FlightLogParameters",
    {
        "autopilot": serializers.CharField(),
        "airframe": serializers.CharField(),
        "source": serializers.CharField(),
        "count": serializers.IntegerField(),
        "parameters": serializers.DictField(),
        "reason": serializers.CharField(required=False),
    },
)
PARAMETER_DIFF = inline_serializer(
    "FlightLogParameterDiff",
    {
        "a": serializers.DictField(),
        "b": serializers.DictField(),
        "same": serializers.IntegerField(),
        "differences": serializers.ListField(child=serializers.DictField()),
    },
)


def _side(label: dict, found: ParameterSet) -> dict:
    return {**label, **{k: v for k, v in found.to_dict().items() if k != "parameters"}}


def _log_label(log: FlightLog) -> dict:
    return {"kind": "log", "id": str(log.pk), "name": log.name, "url": log.get_absolute_url()}


def _require(log: FlightLog, found: ParameterSet) -> None:
    if not found.values:
        raise NoParameters(f"The log {log.name!r} records no parameters ({PARAMETER_SOURCES}).")


def reference_for(log: FlightLog, found: ParameterSet) -> ParameterReference | None:
    return ParameterReference.objects.filter(
        organisation=log.organisation, autopilot=found.autopilot, airframe=found.airframe
    ).first()


def _model_name(found: ParameterSet) -> str:
    return (
        f"{found.autopilot or 'unknown autopilot'} airframe {found.airframe or '(none recorded)'}"
    )


class CompareActions:
    """Mixed into the flight log view set (its get_object, get_queryset and _store)."""

    def _other(self, raw: str | None, name: str) -> FlightLog:
        try:
            pk = uuid.UUID(str(raw))
        except ValueError:
            raise exceptions.ValidationError({name: ["Give a log's id."]}) from None
        # The same reach as the log itself: another organisation's log is not found.
        other = self.get_queryset().filter(pk=pk).first()  # type: ignore[attr-defined]
        if other is None:
            raise exceptions.NotFound("There is no such log among yours.")
        return other

    def _parameters_of(self, log: FlightLog) -> ParameterSet:
        return read_parameters(self._store(log))  # type: ignore[attr-defined]

    @extend_schema(
        parameters=[
            _query(
                "against",
                "Another log's id, or `reference` for the organisation's reference set of "
                "this log's drone model: the differences instead of the set.",
            )
        ],
        responses={200: PARAMETER_SET, 409: None},
    )
    @action(detail=True, methods=["get"])
    def parameters(self, request: Request, pk: str | None = None) -> Response:
        """The log's parameters, or (`?against=`) the parameters that differ."""
        log = self.get_object()  # type: ignore[attr-defined]
        found = self._parameters_of(log)
        against = request.query_params.get("against")
        if not against:
            body = found.to_dict()
            if not found.values:
                body["reason"] = f"this log records no parameters ({PARAMETER_SOURCES})"
            return Response(body)
        _require(log, found)
        if against == REFERENCE:
            ref = reference_for(log, found)
            if ref is None:
                raise exceptions.NotFound(
                    f"No reference parameter set is saved for {_model_name(found)}."
                )
            theirs = ParameterSet(ref.autopilot, ref.airframe, "reference", ref.parameters)
            label = {"kind": "reference", "name": ref.source_name, "saved_at": ref.saved_at}
        else:
            other = self._other(against, "against")
            theirs = self._parameters_of(other)
            _require(other, theirs)
            label = _log_label(other)
        differences = diff(found.values, theirs.values)
        return Response(
            {
                "a": _side(_log_label(log), found),
                "b": _side(label, theirs),
                "same": len(found.values.keys() & theirs.values.keys())
                - sum(d["change"] == "changed" for d in differences),
                "differences": differences,
            }
        )

    @extend_schema(request=None, responses={201: PARAMETER_SET, 409: None})
    @action(detail=True, methods=["post"])
    def reference(self, request: Request, pk: str | None = None) -> Response:
        """Keep this log's parameters as the organisation's reference set for its drone
        model (autopilot and airframe id), replacing any earlier one. Operators and up."""
        log = self.get_object()  # type: ignore[attr-defined]
        found = self._parameters_of(log)
        _require(log, found)
        with transaction.atomic():
            ParameterReference.objects.update_or_create(
                organisation=log.organisation,
                autopilot=found.autopilot,
                airframe=found.airframe,
                defaults={
                    "parameters": found.values,
                    "source_log": log,
                    "source_name": log.name,
                    "saved_by": request.user,
                    "saved_at": timezone.now(),
                },
            )
        return Response(found.to_dict(), status=status.HTTP_201_CREATED)

    @extend_schema(
        parameters=[_query("with", "The other log's id.")],
        responses=inline_serializer(
            "FlightLogComparison",
            {
                "logs": serializers.ListField(child=serializers.DictField()),
                "series": serializers.ListField(child=serializers.CharField()),
            },
        ),
    )
    @action(detail=True, methods=["get"])
    def compare(self, request: Request, pk: str | None = None) -> Response:
        """`?with=<id>`: each log's take-off (seconds since its start, and what said so)
        and the numeric series both recorded, to draw them on one time axis."""
        log = self.get_object()  # type: ignore[attr-defined]
        other = self._other(request.query_params.get("with"), "with")
        stores = [self._store(x) for x in (log, other)]  # type: ignore[attr-defined]
        return Response(
            {
                "logs": [
                    {
                        **_log_label(x),
                        "takeoff": compare.takeoff(s),
                        "start": x.start_s,
                        "duration": x.duration_s,
                    }
                    for x, s in zip((log, other), stores, strict=True)
                ],
                "series": compare.common_series(*stores),
            }
        )

    @extend_schema(
        request=inline_serializer(
            "FlightLogDroneTie",
            {
                "drone": serializers.CharField(allow_null=True),
                "flown_at": serializers.DateTimeField(required=False, allow_null=True),
            },
        ),
        responses=inline_serializer(
            "FlightLogDrone",
            {
                "drone": serializers.CharField(allow_null=True),
                "flown_at": serializers.DateTimeField(allow_null=True),
                "drifts": serializers.ListField(child=serializers.DictField()),
            },
        ),
    )
    @action(detail=True, methods=["post"])
    def drone(self, request: Request, pk: str | None = None) -> Response:
        """Name the drone (of the log's organisation) that flew the log, and when (kept
        when `flown_at` is absent); its figures join that drone's trends and are judged
        against them. Operators and up."""
        log = self.get_object()  # type: ignore[attr-defined]
        ident = request.data.get("drone")
        drone = None
        if ident:
            drone = Drone.objects.filter(organisation=log.organisation, drone_id=ident).first()
            if drone is None:
                raise exceptions.ValidationError(
                    {"drone": ["No drone of the log's organisation has that id."]}
                )
        changes: dict = {"drone": drone}
        # A flight time already known (a collected log's) stays unless one is given.
        if "flown_at" in request.data:
            changes["flown_at"] = _when(request.data.get("flown_at"))
        FlightLog.objects.filter(pk=log.pk).update(**changes)
        log.refresh_from_db()
        drifts = trends.evaluate(log) if drone else []
        return Response(
            {
                "drone": drone.drone_id if drone else None,
                "flown_at": log.flown_at,
                "drifts": [d.to_dict() for d in drifts],
            }
        )


def _when(raw: object) -> object:
    if raw in (None, ""):
        return None
    when = parse_datetime(str(raw))
    if when is None or timezone.is_naive(when):
        raise exceptions.ValidationError(
            {"flown_at": ["Give an ISO 8601 time with its offset, e.g. 2026-05-01T10:00:00Z."]}
        )
    return when


def may_operate(user: object, log: FlightLog) -> bool:
    membership = role_in(user, log.organisation)
    return bool(membership and membership.allows(Role.OPERATOR))

"""REST resources of maintenance (docs/maintenance.md). Members read; organisation admins
write schedules, issue bulletins and sign tasks off. Another organisation's drone,
schedule or bulletin answers 404; a refused body answers 400 naming the field and
changes nothing.

- `GET/POST /api/v1/organisations/{slug}/maintenance/schedules/`
- `GET/PATCH/DELETE /api/v1/maintenance/schedules/{id}/`
- `GET/POST /api/v1/organisations/{slug}/maintenance/bulletins/`
- `GET /api/v1/organisations/{slug}/maintenance/due/`: every drone's items due or due soon
- `GET /api/v1/drones/{id}/maintenance/`: the drone's items with their status
- `GET/POST /api/v1/drones/{id}/maintenance/log/`: the maintenance log; a POST signs off
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from drf_spectacular.utils import extend_schema
from rest_framework import exceptions, status
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from config.api import Pagination
from fleet.lookups import drone_or_404, organisation_or_404
from fleet.models import Organisation, Role
from fleet.permissions import require_role

from . import due, schedules, schema, signoff
from .errors import Refused
from .models import Bulletin, LogEntry, Schedule


class Conflict(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "conflict"
    default_detail = "Conflict."


def _refused(exc: Refused) -> exceptions.APIException:
    if exc.status == status.HTTP_403_FORBIDDEN:
        return exceptions.PermissionDenied(exc.message)
    if exc.status == status.HTTP_409_CONFLICT:
        return Conflict(f"{exc.field}: {exc.message}")
    return exceptions.ValidationError({exc.field: [exc.message]})


def _admin_only(request: Request, organisation: Organisation) -> None:
    if not require_role(request.user, organisation, Role.ADMIN):
        raise exceptions.PermissionDenied("Only organisation admins change maintenance.")


def _created(
    request: Request,
    slug: str,
    make: Callable[[Organisation, Any, Any], Any],
    shown: Callable[[Any], dict],
) -> Response:
    """An admin's new schedule or bulletin in the organisation: 201 with it, or the refusal."""
    organisation = organisation_or_404(request.user, slug)
    _admin_only(request, organisation)
    try:
        made = make(organisation, request.data, request.user)
    except Refused as exc:
        raise _refused(exc) from None
    return Response(shown(made), status=status.HTTP_201_CREATED)


class SchedulesView(APIView):
    """The organisation's schedules. A body: `name`, one target (`drone` id or gear
    `model`), at least one of `every_hours`, `every_flights`, `every_days` (> 0), `notes`."""

    @extend_schema(responses={200: schema.Schedule(many=True)})
    def get(self, request: Request, slug: str) -> Response:
        organisation = organisation_or_404(request.user, slug)
        found = Schedule.objects.filter(organisation=organisation).select_related("drone")
        return Response([schedules.schedule_dict(s) for s in found])

    @extend_schema(request=schema.ScheduleBody, responses={201: schema.Schedule})
    def post(self, request: Request, slug: str) -> Response:
        return _created(request, slug, schedules.create, schedules.schedule_dict)


class ScheduleView(APIView):
    """One schedule; a PATCH changes the fields it gives (checked whole, as a POST)."""

    def _schedule(self, request: Request, pk: int) -> Schedule:
        found = Schedule.objects.for_user(request.user).select_related("drone", "organisation")
        schedule = found.filter(pk=pk).first()
        if schedule is None:
            raise exceptions.NotFound(f"Unknown schedule {pk}.")
        return schedule

    @extend_schema(responses={200: schema.Schedule})
    def get(self, request: Request, pk: int) -> Response:
        return Response(schedules.schedule_dict(self._schedule(request, pk)))

    @extend_schema(request=schema.ScheduleBody(partial=True), responses={200: schema.Schedule})
    def patch(self, request: Request, pk: int) -> Response:
        schedule = self._schedule(request, pk)
        _admin_only(request, schedule.organisation)
        try:
            return Response(schedules.schedule_dict(schedules.change(schedule, request.data)))
        except Refused as exc:
            raise _refused(exc) from None

    @extend_schema(responses={204: None})
    def delete(self, request: Request, pk: int) -> Response:
        """Remove the schedule; its sign-offs stay in the log with the task's name."""
        schedule = self._schedule(request, pk)
        _admin_only(request, schedule.organisation)
        schedule.delete()
        return Response(status=status.HTTP_204_NO_CONTENT)


class BulletinsView(APIView):
    """The organisation's service bulletins; a POST (`model`, `title`, `text`) issues one."""

    @extend_schema(responses={200: schema.Bulletin(many=True)})
    def get(self, request: Request, slug: str) -> Response:
        organisation = organisation_or_404(request.user, slug)
        found = Bulletin.objects.filter(organisation=organisation)
        return Response([schedules.bulletin_dict(b) for b in found])

    @extend_schema(request=schema.BulletinBody, responses={201: schema.Bulletin})
    def post(self, request: Request, slug: str) -> Response:
        return _created(request, slug, schedules.issue_bulletin, schedules.bulletin_dict)


class DueView(APIView):
    """Every drone of the organisation with items due or due soon."""

    @extend_schema(responses={200: schema.DroneItems(many=True)})
    def get(self, request: Request, slug: str) -> Response:
        organisation = organisation_or_404(request.user, slug)
        return Response(
            [
                {"drone": drone.drone_id, "items": [i.to_dict() for i in found]}
                for drone, found in due.fleet_due(organisation)
            ]
        )


class DroneItemsView(APIView):
    """The drone's maintenance items (schedules and open bulletins) with their status."""

    @extend_schema(responses={200: schema.DroneItems})
    def get(self, request: Request, drone_id: str) -> Response:
        drone = drone_or_404(request.user, drone_id)
        return Response({"drone": drone.drone_id, "items": [i.to_dict() for i in due.items(drone)]})


class DroneLogView(APIView):
    """The drone's maintenance log, newest first; a POST signs a task off (`schedule` or
    `bulletin` id, `notes`, optional `parts`): admins only, never changed afterwards."""

    @extend_schema(responses={200: schema.LogPage})
    def get(self, request: Request, drone_id: str) -> Response:
        drone = drone_or_404(request.user, drone_id)
        paginator = Pagination()
        entries = LogEntry.objects.filter(drone=drone)
        page = paginator.paginate_queryset(entries, request, view=self)
        return paginator.get_paginated_response([signoff.entry_dict(e) for e in page])

    @extend_schema(request=schema.SignOffBody, responses={201: schema.LogEntry})
    def post(self, request: Request, drone_id: str) -> Response:
        drone = drone_or_404(request.user, drone_id)
        try:
            entry = signoff.sign_off(drone, request.data, request.user)
        except Refused as exc:
            raise _refused(exc) from None
        return Response(signoff.entry_dict(entry), status=status.HTTP_201_CREATED)

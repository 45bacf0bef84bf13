"""REST resources of pre-flight checklists (docs/checklists.md).

- `GET/POST /api/v1/organisations/{slug}/checklists/`: templates; members read, admins
  create.
- `GET/PUT/DELETE /api/v1/organisations/{slug}/checklists/{id}/`: one template; admins
  change it or retire it (DELETE: its runs stay).
- `GET/PUT /api/v1/organisations/{slug}/checklist-rule/`: `required`, `valid_minutes`;
  members read, admins write.
- `GET/POST /api/v1/drones/{id}/checklists/`: the drone's checklist state and recent runs;
  operators and admins run one.

Another organisation's drone, template or organisation answers 404; bad input answers 400
naming the field, and nothing changes.
"""

from __future__ import annotations

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import exceptions, status
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from fleet.models import Drone, Membership, Organisation, Role
from fleet.permissions import require_role

from . import definitions, gate, runs
from .items import ChecklistError
from .models import Run, Template

RECENT_RUNS = 20


def _drone(request: Request, drone_id: str) -> Drone:
    drone = (
        Drone.objects.for_user(request.user)
        .select_related("organisation")
        .filter(drone_id=drone_id)
        .first()
    )
    if drone is None:
        raise exceptions.NotFound(f"Unknown drone {drone_id!r}.")
    return drone


def _organisation(request: Request, slug: str) -> Organisation:
    membership = Membership.objects.for_user(request.user).filter(organisation__slug=slug).first()
    if membership is None:
        raise exceptions.NotFound(f"Unknown organisation {slug!r}.")
    return membership.organisation


def _require(request: Request, organisation: Organisation, role: str, doing: str) -> None:
    if not require_role(request.user, organisation, role):
        raise exceptions.PermissionDenied(f"Only {role}s and above {doing}.")


def _bad(exc: ChecklistError) -> exceptions.ValidationError:
    return exceptions.ValidationError({exc.field: [exc.message]})


def _template(organisation: Organisation, pk: int) -> Template:
    template = Template.objects.filter(organisation=organisation, pk=pk, active=True).first()
    if template is None:
        raise exceptions.NotFound(f"Unknown checklist template {pk}.")
    return template


class TemplatesView(APIView):
    """The organisation's active checklist templates."""

    @extend_schema(
        operation_id="api_v1_organisations_checklists_list", responses={200: OpenApiTypes.OBJECT}
    )
    def get(self, request: Request, slug: str) -> Response:
        organisation = _organisation(request, slug)
        found = Template.objects.filter(organisation=organisation, active=True)
        return Response({"templates": [definitions.template_dict(t) for t in found]})

    @extend_schema(request=OpenApiTypes.OBJECT, responses={201: OpenApiTypes.OBJECT})
    def post(self, request: Request, slug: str) -> Response:
        organisation = _organisation(request, slug)
        _require(request, organisation, Role.ADMIN, "define checklists")
        try:
            template = definitions.create_template(organisation, request.data, request.user)
        except ChecklistError as exc:
            raise _bad(exc) from None
        return Response(definitions.template_dict(template), status=status.HTTP_201_CREATED)


class TemplateView(APIView):
    """One template: `name`, `items` (manual and automatic), `valid_minutes`."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str, pk: int) -> Response:
        return Response(definitions.template_dict(_template(_organisation(request, slug), pk)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str, pk: int) -> Response:
        organisation = _organisation(request, slug)
        _require(request, organisation, Role.ADMIN, "define checklists")
        try:
            template = definitions.update_template(
                _template(organisation, pk), request.data, request.user
            )
        except ChecklistError as exc:
            raise _bad(exc) from None
        return Response(definitions.template_dict(template))

    @extend_schema(responses={204: None})
    def delete(self, request: Request, slug: str, pk: int) -> Response:
        organisation = _organisation(request, slug)
        _require(request, organisation, Role.ADMIN, "define checklists")
        definitions.retire_template(_template(organisation, pk), request.user)
        return Response(status=status.HTTP_204_NO_CONTENT)


class RuleView(APIView):
    """Whether the organisation needs checklists, and how long a passed one is good for."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str) -> Response:
        return Response(gate.rule_of(_organisation(request, slug)).to_dict())

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str) -> Response:
        organisation = _organisation(request, slug)
        _require(request, organisation, Role.ADMIN, "set the checklist rule")
        try:
            return Response(
                definitions.set_rule(organisation, request.data, request.user).to_dict()
            )
        except ChecklistError as exc:
            raise _bad(exc) from None


class DroneChecklistsView(APIView):
    """The drone's checklist state and its recent runs; POST runs one:
    `{"template": id, "answers": [true/false per manual item, in order]}`."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        recent = Run.objects.filter(drone=drone).select_related("drone")[:RECENT_RUNS]
        return Response({"state": gate.state_of(drone), "runs": [runs.run_dict(r) for r in recent]})

    @extend_schema(request=OpenApiTypes.OBJECT, responses={201: OpenApiTypes.OBJECT})
    def post(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        _require(request, drone.organisation, Role.OPERATOR, "run checklists")
        try:
            run = runs.run_checklist(drone, request.data, request.user)
        except ChecklistError as exc:
            raise _bad(exc) from None
        return Response(runs.run_dict(run), status=status.HTTP_201_CREATED)

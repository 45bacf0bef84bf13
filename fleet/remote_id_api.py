"""REST resources of Remote ID and airworthiness (docs/remote-id.md).

- `GET/PUT /api/v1/drones/{id}/identity/`: the drone's serial number and external module
  declaration; members read, admins write.
- `GET/PUT /api/v1/organisations/{slug}/remote-id/`: the operator registration number and
  whether Remote ID is required; members read, admins write.
- `GET /api/v1/drones/{id}/airworthiness/`: `{"airworthy": bool, "reasons": [...]}`.

Another organisation's drone or organisation answers 404; a refused number answers 400
naming the field, and nothing changes.
"""

from __future__ import annotations

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import exceptions, serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from . import airworthiness, remote_id
from .identity import IdentityError
from .lookups import drone_or_404, organisation_or_404
from .models import Drone, Organisation, Role
from .permissions import require_role


def _drone(request: Request, drone_id: str) -> Drone:
    return drone_or_404(request.user, drone_id)


def _organisation(request: Request, slug: str) -> Organisation:
    return organisation_or_404(request.user, slug)


def _admin_only(request: Request, organisation: Organisation) -> None:
    if not require_role(request.user, organisation, Role.ADMIN):
        raise exceptions.PermissionDenied("Only admins set Remote ID identities.")


def _bad(exc: IdentityError) -> exceptions.ValidationError:
    return exceptions.ValidationError({exc.field: [exc.message]})


class DroneIdentityView(APIView):
    """The drone's Remote ID identity: `serial_number` (ANSI/CTA-2063-A) and
    `remote_id_external` (an external broadcast module is fitted)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, drone_id: str) -> Response:
        return Response(remote_id.drone_identity(_drone(request, drone_id)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        _admin_only(request, drone.organisation)
        try:
            return Response(remote_id.set_drone_identity(drone, request.data, request.user))
        except IdentityError as exc:
            raise _bad(exc) from None


class OrganisationRemoteIdView(APIView):
    """The organisation's `operator_id` (EU EN 4709-002 with its 3 secret characters, which
    are checked and never stored, or FAA) and `require_remote_id`."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str) -> Response:
        return Response(remote_id.organisation_remote_id(_organisation(request, slug)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str) -> Response:
        organisation = _organisation(request, slug)
        _admin_only(request, organisation)
        try:
            return Response(
                remote_id.set_organisation_remote_id(organisation, request.data, request.user)
            )
        except IdentityError as exc:
            raise _bad(exc) from None


AIRWORTHINESS = inline_serializer(
    "Airworthiness",
    {
        "airworthy": serializers.BooleanField(),
        "reasons": serializers.ListField(
            child=serializers.CharField(), help_text="each reason it may not arm, in order"
        ),
    },
)


class AirworthinessView(APIView):
    """Whether the drone may be armed, and every reason it may not."""

    @extend_schema(responses={200: AIRWORTHINESS})
    def get(self, request: Request, drone_id: str) -> Response:
        return Response(airworthiness.verdict(_drone(request, drone_id)).to_dict())

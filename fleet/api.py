"""REST resources of the fleet: drones of the user's organisations, and the user itself."""

from __future__ import annotations

from typing import Any

from asgiref.sync import sync_to_async
from django.conf import settings
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiResponse, extend_schema, inline_serializer
from rest_framework import exceptions, serializers, status, viewsets
from rest_framework.decorators import (
    action,
    api_view,
)
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from config.api import RefusalSerializer, StrictSerializer
from config.throttling import COMMAND_THROTTLES, TogetherThrottles
from onboard.envelope import EnvelopeError

from . import commands, credentials, envelopes
from .async_views import AsyncAPIView
from .commands import CommandRefused
from .models import Drone, Membership, Organisation, Role
from .permissions import OrganisationRole, require_role
from .serializers import (
    ConnectionEventSerializer,
    DroneDetailSerializer,
    DroneSerializer,
    MembershipSerializer,
)
from .signals import note_refusal

GearSerializer = inline_serializer(
    "Gear",
    {
        "drone_id": serializers.CharField(),
        "specs": serializers.DictField(),
        "sensors": serializers.DictField(),
    },
)
CredentialsSerializer = inline_serializer(
    "BrokerCredentials",
    {
        "drone_id": serializers.CharField(),
        "mqtt": inline_serializer(
            "BrokerAccount",
            {
                "host": serializers.CharField(),
                "port": serializers.IntegerField(),
                "username": serializers.CharField(),
                "password": serializers.CharField(),
            },
        ),
    },
)


class DroneViewSet(viewsets.ReadOnlyModelViewSet):
    """Drones of the organisations the user belongs to; others answer 404."""

    lookup_field = "drone_id"
    lookup_value_regex = r"[A-Za-z0-9_-]{1,64}"
    permission_classes = [OrganisationRole]

    def get_queryset(self):  # type: ignore[no-untyped-def]
        return Drone.objects.for_user(self.request.user).select_related("organisation")

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        if self.action == "connections":
            return ConnectionEventSerializer
        return DroneDetailSerializer if self.action == "retrieve" else DroneSerializer

    @extend_schema(responses=GearSerializer)
    @action(detail=True, methods=["get"])
    def gear(self, request: Request, drone_id: str | None = None) -> Response:
        """Specs and sensors the drone last announced (the Drone Identifier's `getgear`)."""
        return Response(commands.gear(self.get_object()))

    @action(detail=True, methods=["get"])
    def connections(self, request: Request, drone_id: str | None = None) -> Response:
        """Connection history: online/offline events, newest first."""
        events = self.get_object().connection_events.all()
        page = self.paginate_queryset(events)
        return self.get_paginated_response(ConnectionEventSerializer(page, many=True).data)

    @extend_schema(
        methods=["POST"],
        request=None,
        responses={201: CredentialsSerializer},
        description="New broker credentials (admin role). The password is shown once.",
    )
    @extend_schema(methods=["DELETE"], request=None, responses={204: None})
    @action(detail=True, methods=["post", "delete"])
    def credentials(self, request: Request, drone_id: str | None = None) -> Response:
        """Issue (POST) or revoke (DELETE) the drone's broker credentials; admins only."""
        drone = self.get_object()
        if not require_role(request.user, drone.organisation, Role.ADMIN):
            raise exceptions.PermissionDenied("Only admins manage broker credentials.")
        if request.method == "DELETE":
            credentials.revoke(drone)
            return Response(status=status.HTTP_204_NO_CONTENT)
        try:
            issued = credentials.provision(drone.drone_id, drone.organisation.slug)
        except credentials.ProvisioningError as exc:
            raise exceptions.ValidationError({"drone_id": [str(exc)]}) from None
        return Response(issued.to_dict(), status=status.HTTP_201_CREATED)


class CommandRequestSerializer(StrictSerializer):
    command = serializers.ChoiceField(choices=commands.API_COMMANDS)
    params = serializers.DictField(required=False, default=dict)
    confirm_beyond_defaults = serializers.BooleanField(
        required=False,
        default=False,
        help_text=(
            "The operator confirmed a move beyond the envelope's defaults (120 m high, "
            "1000 m from home); without it such a move answers 409 confirmation_required."
        ),
    )


CommandReplySerializer = inline_serializer(
    "CommandReply",
    {
        "request_id": serializers.CharField(),
        "command": serializers.CharField(),
        "ok": serializers.BooleanField(),
        "result": serializers.DictField(allow_null=True),
        "error": serializers.CharField(allow_null=True),
        "terrain_warnings": serializers.ListField(
            child=serializers.DictField(),
            required=False,
            help_text="Where the move's terrain clearance could not be checked (no terrain "
            "or voids under its leg, or at home): `step`, `message`, `gaps`. Absent when none.",
        ),
    },
)


class Conflict(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "conflict"


class NoReply(exceptions.APIException):
    status_code = status.HTTP_504_GATEWAY_TIMEOUT
    default_code = "no_reply"


def _api_error(refusal: CommandRefused) -> exceptions.APIException:
    if refusal.status == 400:
        return exceptions.ValidationError({refusal.field or "params": [refusal.message]})
    if refusal.status == 403:
        return exceptions.PermissionDenied(refusal.message)
    if refusal.status == 404:
        return exceptions.NotFound(refusal.message)
    conflict = Conflict(refusal.message, code=refusal.code)
    if refusal.reasons is not None:
        conflict.extra_body = {"reasons": refusal.reasons}  # type: ignore[attr-defined]
    return conflict


def command_reply(
    drone_id: str, outcome: commands.Outcome, terrain_warnings: list | None = None
) -> Response:
    """The answer to a sent command: the drone's own reply, or NoReply (504) without one;
    `terrain_warnings` where its terrain clearance could not be checked, when any."""
    if outcome.timed_out:
        raise NoReply(f"No reply from {drone_id} within {settings.COMMAND_TIMEOUT_S:g} s.")
    reply = outcome.reply or {}
    return Response(
        {
            "request_id": outcome.request_id,
            "command": outcome.command,
            "ok": bool(reply.get("ok")),
            "result": reply.get("result"),
            "error": reply.get("error"),
            **({"terrain_warnings": terrain_warnings} if terrain_warnings else {}),
        }
    )


class DroneCommandView(TogetherThrottles, AsyncAPIView):
    """`POST /api/v1/drones/{drone_id}/commands/`: the drone's own reply, or an error."""

    permission_classes = [OrganisationRole]
    throttle_classes = COMMAND_THROTTLES
    prepared: commands.Prepared | None = None

    def _prepare(self, request: Request, *args: Any, **kwargs: Any) -> None:
        """Authentication, the body and every check before sending, in one worker-thread
        step: each step to a thread and back is on every command's round trip."""
        super()._prepare(request, *args, **kwargs)
        if request.method != "POST":
            return
        serializer = CommandRequestSerializer(data=request.data)
        serializer.is_valid(raise_exception=True)
        self.order = serializer.validated_data
        command = self.order["command"]
        if command in commands.CHAIN_COMMANDS:
            return
        try:
            self.prepared = commands.prepare(
                request.user,
                kwargs["drone_id"],
                command,
                self.order["params"],
                self.order["confirm_beyond_defaults"],
            )
        except CommandRefused as refusal:
            raise _api_error(refusal) from None

    @extend_schema(
        operation_id="drones_commands_create",
        request=CommandRequestSerializer,
        responses={
            200: CommandReplySerializer,
            400: OpenApiResponse(description="bad command or parameter (named in `fields`)"),
            403: OpenApiResponse(description="viewers may not command"),
            404: OpenApiResponse(description="unknown drone"),
            409: OpenApiResponse(
                response=RefusalSerializer,
                description=(
                    "drone offline or unsafe; `code: outside_envelope` when the move leaves "
                    "the flight envelope, `code: terrain_clearance` when its leg comes below "
                    "the organisation's minimum terrain clearance, `code: "
                    "confirmation_required` when it goes beyond the envelope's defaults "
                    "without `confirm_beyond_defaults`, `code: not_airworthy` when an arm "
                    "finds the drone not airworthy (the reasons in `error` and, one by one, in "
                    "`reasons`), `code: "
                    "checklist_required` when an arm, or a take-off that arms, finds no "
                    "passed pre-flight checklist for the drone within its validity "
                    "(docs/checklists.md), `code: wind` when an arm or a take-off meets "
                    "a wind above the drone's limit (the figure in `error`, "
                    "docs/airspace.md), `code: zone` when the move enters a published "
                    "zone within its band (the zone's name and band in `error`), `code: "
                    "conflict` when it comes within the separation minima of another "
                    "drone's reservation (the other drone, the place and the time in "
                    "`error`, docs/airspace.md)"
                ),
            ),
            504: OpenApiResponse(description="no reply in time"),
        },
        description=(
            "Send one command of the `/control` command set (`params` as in docs/protocol.md). "
            "A reply with "
            "`ok: false` is the drone's own refusal. A move inside the organisation's "
            "envelope but beyond its defaults (higher than 120 m or farther than 1000 m "
            "from home) is sent only with `confirm_beyond_defaults: true`; nothing is sent "
            "otherwise."
        ),
    )
    async def post(self, request: Request, drone_id: str) -> Response:
        command = self.order["command"]
        if self.prepared is None:
            return await self.chain(request, drone_id, command)
        outcome = await commands.execute(self.prepared, after_answer=self.after_answer)
        return command_reply(drone_id, outcome, self.prepared.terrain_warnings)

    async def chain(self, request: Request, drone_id: str, command: str) -> Response:
        """startchain / stopchain: the Mission Planner's hooks answer, not the drone."""
        try:
            result = await sync_to_async(commands.run_mission_start_stop)(
                request.user,
                drone_id,
                command,
                self.order["params"].get("mission"),
                self.order["confirm_beyond_defaults"],
            )
        except CommandRefused as refusal:
            raise _api_error(refusal) from None
        return Response(
            {"request_id": "", "command": command, "ok": True, "result": result, "error": None}
        )


@extend_schema(
    responses=inline_serializer(
        "Me",
        {
            "username": serializers.CharField(),
            "memberships": MembershipSerializer(many=True),
        },
    )
)
@api_view(["GET"])
def me(request: Request) -> Response:
    memberships = Membership.objects.for_user(request.user)
    return Response(
        {
            "username": request.user.get_username(),
            "memberships": MembershipSerializer(memberships, many=True).data,
        }
    )


def _member_organisation(request: Request, slug: str) -> Organisation:
    membership = Membership.objects.for_user(request.user).filter(organisation__slug=slug).first()
    if membership is None:
        raise exceptions.NotFound(f"Unknown organisation {slug!r}.")
    return membership.organisation


class EnvelopeView(APIView):
    """`GET/PUT /api/v1/organisations/{slug}/envelope/`: the organisation's flight envelope.

    PUT takes the envelope (limits and a QGroundControl `geoFence`) or a whole `.plan`
    file (its geoFence, with its planned home as home); admins only. A malformed envelope
    answers 400 naming the field and leaves the stored one in force.
    """

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str) -> Response:
        return Response(envelopes.envelope_body(_member_organisation(request, slug)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str) -> Response:
        organisation = _member_organisation(request, slug)
        if not require_role(request.user, organisation, Role.ADMIN):
            raise exceptions.PermissionDenied("Only admins change the flight envelope.")
        try:
            envelopes.set_envelope(organisation, request.data)
        except EnvelopeError as exc:
            note_refusal(organisation.pk, request.user, "envelope.change", organisation, str(exc))
            raise exceptions.ValidationError({exc.field: [exc.message]}) from None
        return Response(envelopes.envelope_body(organisation))


@extend_schema(responses={(200, "application/json"): OpenApiTypes.OBJECT})
@api_view(["GET"])
def envelope_plan(request: Request, slug: str) -> Response:
    """The organisation's geofence as a QGroundControl `.plan` file (no mission items)."""
    organisation = _member_organisation(request, slug)
    response = Response(envelopes.plan_document(organisation))
    response["Content-Disposition"] = f'attachment; filename="{slug}-geofence.plan"'
    return response

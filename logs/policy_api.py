"""REST: `GET/PUT /api/v1/logs/collection/{drone_id}/`, a drone's log collection mode
(logs/policy.py). Members read; operators and admins write. Another organisation's drone
answers 404; a refused value answers 400 naming the field, and nothing changes."""

from __future__ import annotations

from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import exceptions, serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from fleet.lookups import drone_or_404
from fleet.models import LogCollection, Role
from fleet.permissions import require_role
from logs import policy

_MODE = serializers.ChoiceField(
    choices=LogCollection.choices,
    help_text="always: every link; ground_links: only on Wi-Fi or wired ground links; "
    "off: the drone uploads nothing after landing.",
)
POLICY_SCHEMA = inline_serializer(
    "DroneLogCollection",
    {"drone_id": serializers.CharField(read_only=True), "log_collection": _MODE},
)
CHANGE_SCHEMA = inline_serializer("DroneLogCollectionChange", {"log_collection": _MODE})


class DroneLogCollectionView(APIView):
    """When the drone uploads its logs after landing; sent to it with its envelope."""

    @extend_schema(responses={200: POLICY_SCHEMA})
    def get(self, request: Request, drone_id: str) -> Response:
        return Response(policy.drone_policy(drone_or_404(request.user, drone_id)))

    @extend_schema(request=CHANGE_SCHEMA, responses={200: POLICY_SCHEMA})
    def put(self, request: Request, drone_id: str) -> Response:
        drone = drone_or_404(request.user, drone_id)
        if not require_role(request.user, drone.organisation, Role.OPERATOR):
            raise exceptions.PermissionDenied("Only operators and admins set log collection.")
        try:
            return Response(policy.set_drone_policy(drone, request.data, request.user))
        except policy.PolicyError as exc:
            raise exceptions.ValidationError({exc.field: [exc.message]}) from None

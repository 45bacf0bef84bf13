"""REST resources of batteries (docs/batteries.md).

- `GET /api/v1/batteries/`, `GET /api/v1/batteries/{id}/`: the packs of the user's
  organisations with their cycles, energy, age and health (members); `POST` names a new
  pack, `PATCH` sets its rated energy (operators, as for drones).
- `GET/PUT /api/v1/drones/{id}/battery/`: the pack the drone carries; `PUT {"battery": id
  or null}` chooses it (operators), refused when the flight controller reports its pack.
- `GET/PUT /api/v1/organisations/{slug}/battery-policy/`: health threshold and cycle
  limit (members read, admins write).

Another organisation's pack, drone or organisation answers 404; a refused value answers
400 naming the field, and nothing changes.
"""

from __future__ import annotations

from typing import Any

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import exceptions, mixins, serializers, status, viewsets
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from fleet.models import Drone, Membership, Organisation, Role
from fleet.permissions import OrganisationRole, require_role
from fleet.tenancy import acting_organisation

from . import fitting, policy, usage
from .fitting import BatteryRefused
from .models import Battery, BatteryFlight


class BatterySerializer(serializers.ModelSerializer):
    organisation = serializers.SlugRelatedField(slug_field="slug", read_only=True)
    drone = serializers.SlugRelatedField(slug_field="drone_id", read_only=True)
    age_days = serializers.FloatField(read_only=True)

    class Meta:
        model = Battery
        fields = [
            "id", "organisation", "serial", "reported", "drone", "rated_energy_wh",
            "in_service_since", "age_days", "flights", "cycles", "energy_wh", "capacity_wh",
            "resistance_ohm", "health", "retired", "retired_reason",
        ]  # fmt: skip
        read_only_fields = fields


class BatteryFlightSerializer(serializers.ModelSerializer):
    class Meta:
        model = BatteryFlight
        fields = [
            "record", "started_at", "soc_drop", "cycles", "energy_wh", "capacity_wh",
            "resistance_ohm",
        ]  # fmt: skip


class BatteryDetailSerializer(BatterySerializer):
    uses = serializers.SerializerMethodField()

    class Meta(BatterySerializer.Meta):
        fields = [*BatterySerializer.Meta.fields, "uses"]
        read_only_fields = fields

    def get_uses(self, battery: Battery) -> list[dict]:
        """The pack's newest flights (at most 100)."""
        return BatteryFlightSerializer(battery.uses.all()[:100], many=True).data


class NewBatterySerializer(serializers.Serializer):
    organisation = serializers.SlugField(required=False, help_text="default: the acting one")
    serial = serializers.CharField(max_length=64)
    rated_energy_wh = serializers.FloatField(required=False, allow_null=True)


def _refused(exc: BatteryRefused) -> exceptions.ValidationError:
    return exceptions.ValidationError({exc.field: [exc.message]})


class BatteryViewSet(
    mixins.ListModelMixin,
    mixins.RetrieveModelMixin,
    mixins.CreateModelMixin,
    mixins.UpdateModelMixin,
    viewsets.GenericViewSet,
):
    """Packs of the organisations the user belongs to; others answer 404."""

    permission_classes = [OrganisationRole]
    http_method_names = ["get", "post", "patch", "head", "options"]

    def get_queryset(self):  # type: ignore[no-untyped-def]
        packs = Battery.objects.for_user(self.request.user).select_related("organisation", "drone")
        drone = self.request.query_params.get("drone")
        return packs.filter(drone__drone_id=drone) if drone else packs

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        return BatteryDetailSerializer if self.action == "retrieve" else BatterySerializer

    @extend_schema(parameters=[OpenApiParameter("drone", str, description="carried by")])
    def list(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        fitting.sync(Drone.objects.for_user(request.user).filter(fc__has_key="battery_serial"))
        return super().list(request, *args, **kwargs)

    @extend_schema(request=NewBatterySerializer, responses={201: BatterySerializer})
    def create(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        data = dict(request.data) if isinstance(request.data, dict) else request.data
        organisation = _writable_organisation(request, data)
        try:
            battery = policy.new_battery(organisation, data, request.user)
        except BatteryRefused as exc:
            raise _refused(exc) from None
        return Response(BatterySerializer(battery).data, status=status.HTTP_201_CREATED)

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: BatterySerializer})
    def partial_update(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        battery = self.get_object()
        try:
            policy.set_rating(battery, request.data, request.user)
        except BatteryRefused as exc:
            raise _refused(exc) from None
        return Response(BatterySerializer(battery).data)

    @extend_schema(exclude=True)
    def update(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        raise exceptions.MethodNotAllowed("PUT")


def _writable_organisation(request: Request, data: Any) -> Organisation:
    """The organisation named in `organisation` (else the acting one) where the user may
    write (operator); 404 when the user is not a member."""
    slug = data.pop("organisation", None) if isinstance(data, dict) else None
    if slug is None:
        organisation = acting_organisation(request)
    else:
        found = Membership.objects.for_user(request.user).filter(organisation__slug=slug).first()
        organisation = found.organisation if found else None
    if organisation is None:
        raise exceptions.NotFound("Unknown organisation.")
    if not require_role(request.user, organisation, Role.OPERATOR):
        raise exceptions.PermissionDenied("Only operators and admins name batteries.")
    return organisation


def _drone(request: Request, drone_id: str) -> Drone:
    drone = Drone.objects.for_user(request.user).filter(drone_id=drone_id).first()
    if drone is None:
        raise exceptions.NotFound(f"Unknown drone {drone_id!r}.")
    return drone


def _carried(drone: Drone) -> dict:
    battery = fitting.carried(drone)
    return {
        "drone": drone.drone_id,
        "reported_serial": fitting.reported_serial(drone),
        "battery": None if battery is None else BatterySerializer(battery).data,
    }


class DroneBatteryView(APIView):
    """The pack the drone carries: reported by its flight controller, or chosen."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, drone_id: str) -> Response:
        return Response(_carried(_drone(request, drone_id)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        if not require_role(request.user, drone.organisation, Role.OPERATOR):
            raise exceptions.PermissionDenied("Only operators and admins choose batteries.")
        if not hasattr(request.data, "keys") or set(request.data) != {"battery"}:
            raise exceptions.ValidationError({"battery": ['send {"battery": id or null}']})
        try:
            fitting.choose(drone, request.data["battery"], request.user)
        except BatteryRefused as exc:
            raise _refused(exc) from None
        return Response(_carried(drone))


class BatteryPolicyView(APIView):
    """The organisation's `health_threshold` (0..1) and `cycle_limit` (null: none)."""

    def _organisation(self, request: Request, slug: str) -> Organisation:
        found = Membership.objects.for_user(request.user).filter(organisation__slug=slug).first()
        if found is None:
            raise exceptions.NotFound(f"Unknown organisation {slug!r}.")
        return found.organisation

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str) -> Response:
        organisation = self._organisation(request, slug)
        return Response(policy.describe_policy(usage.policy_of(organisation.pk), slug))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str) -> Response:
        organisation = self._organisation(request, slug)
        if not require_role(request.user, organisation, Role.ADMIN):
            raise exceptions.PermissionDenied("Only admins set battery rules.")
        try:
            rules = policy.set_policy(organisation, request.data, request.user)
        except BatteryRefused as exc:
            raise _refused(exc) from None
        return Response(policy.describe_policy(rules, slug))

"""REST resources of the fleet: drones of the user's organisations, and the user itself."""

from __future__ import annotations

from django.contrib.auth import authenticate
from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import exceptions, serializers, viewsets
from rest_framework.authtoken.models import Token
from rest_framework.decorators import api_view, authentication_classes, permission_classes
from rest_framework.permissions import AllowAny
from rest_framework.request import Request
from rest_framework.response import Response

from config.api import StrictSerializer

from .models import Drone, Membership
from .permissions import OrganisationRole
from .serializers import DroneDetailSerializer, DroneSerializer, MembershipSerializer


class DroneViewSet(viewsets.ReadOnlyModelViewSet):
    """Drones of the organisations the user belongs to; others answer 404."""

    lookup_field = "drone_id"
    lookup_value_regex = r"[A-Za-z0-9_-]{1,64}"
    permission_classes = [OrganisationRole]

    def get_queryset(self):  # type: ignore[no-untyped-def]
        return Drone.objects.for_user(self.request.user).select_related("organisation")

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        return DroneDetailSerializer if self.action == "retrieve" else DroneSerializer


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


class TokenRequestSerializer(StrictSerializer):
    username = serializers.CharField()
    password = serializers.CharField(style={"input_type": "password"}, trim_whitespace=False)


@extend_schema(
    request=TokenRequestSerializer,
    responses=inline_serializer("Token", {"token": serializers.CharField()}),
    auth=[],
)
@api_view(["POST"])
@authentication_classes([])
@permission_classes([AllowAny])
def obtain_token(request: Request) -> Response:
    """Exchange a username and password for an API token (header `Authorization: Token …`)."""
    serializer = TokenRequestSerializer(data=request.data)
    serializer.is_valid(raise_exception=True)
    user = authenticate(
        request=request._request,
        username=serializer.validated_data["username"],
        password=serializer.validated_data["password"],
    )
    if user is None or not user.is_active:
        raise exceptions.AuthenticationFailed("Unable to log in with the provided credentials.")
    token, _ = Token.objects.get_or_create(user=user)
    return Response({"token": token.key})

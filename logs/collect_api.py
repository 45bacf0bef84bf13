"""REST: the drones' own log uploads (`/api/v1/logs/collect/`), authenticated as the drone.

A drone signs in with HTTP Basic: its drone id and the broker password `provision_drone`
gave it, checked against the hash the ground keeps for the broker
(`Drone.mqtt_password_hash`); a drone whose credentials were revoked is refused. Only a
drone reaches these addresses, and only its own uploads (logs.collection keys every row
by drone). People's tokens and sessions are not accepted here.
"""

from __future__ import annotations

import base64
import binascii
from datetime import UTC, datetime

from drf_spectacular.extensions import OpenApiAuthenticationExtension
from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import authentication, exceptions, permissions, serializers, status
from rest_framework.parsers import BaseParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from config.throttling import LoginAttempts
from fleet.credentials import check_password
from fleet.models import Drone
from logs import collection
from logs.models import CollectedLogKind


class DronePrincipal:
    """request.user for a drone: authenticated, no person, no staff rights."""

    is_authenticated = True
    is_active = True
    is_staff = False
    is_superuser = False

    def __init__(self, drone: Drone) -> None:
        self.drone = drone
        self.pk = None

    def __str__(self) -> str:
        return f"drone {self.drone.drone_id}"


class DroneAuthentication(authentication.BaseAuthentication):
    """HTTP Basic with the drone id and its broker password."""

    def authenticate(self, request: Request) -> tuple[DronePrincipal, Drone] | None:
        header = authentication.get_authorization_header(request).split()
        if not header or header[0].lower() != b"basic":
            return None
        if len(header) != 2:
            raise exceptions.AuthenticationFailed("Malformed Basic credentials.")
        try:
            drone_id, _, password = base64.b64decode(header[1]).decode().partition(":")
        except (binascii.Error, UnicodeDecodeError):
            raise exceptions.AuthenticationFailed("Malformed Basic credentials.") from None
        # Failed sign-ins count against LOGIN_RATE per address and per drone id, as a
        # person's do: a drone's password is guessed no faster than a person's.
        attempts = LoginAttempts(request, username=f"drone:{drone_id}")
        if attempts.exhausted():
            raise exceptions.Throttled(detail="Too many failed drone sign-ins; try again later.")
        drone = Drone.objects.filter(drone_id=drone_id, credentials_revoked=False).first()
        known = drone is not None and bool(drone.mqtt_password_hash)
        if not known or not check_password(password, drone.mqtt_password_hash):
            attempts.failed()
            raise exceptions.AuthenticationFailed("Unknown drone or wrong password.")
        return DronePrincipal(drone), drone

    def authenticate_header(self, request: Request) -> str:
        return 'Basic realm="skyhive drones"'


class DroneAuthenticationScheme(OpenApiAuthenticationExtension):
    """The schema's name for the drones' sign-in: HTTP Basic."""

    target_class = DroneAuthentication
    name = "droneBasic"

    def get_security_definition(self, auto_schema):  # type: ignore[no-untyped-def]
        return {
            "type": "http",
            "scheme": "basic",
            "description": "The drone id and the broker password provision_drone gave it.",
        }


class IsDrone(permissions.BasePermission):
    def has_permission(self, request, view) -> bool:  # type: ignore[no-untyped-def]
        return isinstance(request.auth, Drone)


class OctetStreamParser(BaseParser):
    """A chunk's raw bytes (the body limit of the address bounds its size)."""

    media_type = "application/octet-stream"

    def parse(self, stream, media_type=None, parser_context=None) -> bytes:  # type: ignore[no-untyped-def]
        return stream.read() if stream is not None else b""


class OfferSerializer(serializers.Serializer):
    kind = serializers.ChoiceField(CollectedLogKind.values)
    name = serializers.CharField(max_length=255)
    size = serializers.IntegerField(min_value=1)
    sha256 = serializers.RegexField(collection.SHA256_RE)
    flight_start = serializers.FloatField(help_text="Armed, seconds since the epoch (UTC).")
    flight_end = serializers.FloatField(help_text="Disarmed, seconds since the epoch (UTC).")

    def validate(self, attrs: dict) -> dict:
        for name in ("flight_start", "flight_end"):
            if not 0 < attrs[name] < 4102444800:  # 1970 to 2100, as the wire contract says
                raise serializers.ValidationError({name: ["Not a time between 1970 and 2100."]})
        return attrs


UPLOAD = inline_serializer(
    "CollectedLogUpload",
    {
        "id": serializers.UUIDField(),
        "kind": serializers.CharField(),
        "name": serializers.CharField(),
        "size": serializers.IntegerField(),
        "received": serializers.IntegerField(help_text="Bytes held: the next chunk's offset."),
        "status": serializers.ChoiceField(["receiving", "stored"]),
        "log": serializers.UUIDField(allow_null=True),
    },
)


def _refusal(exc: collection.CollectionRefused) -> Response:
    body: dict = {"code": exc.code, "detail": exc.message}
    if exc.received is not None:
        body["received"] = exc.received
    return Response(body, status=exc.status)


def _epoch(value: float) -> datetime:
    return datetime.fromtimestamp(value, UTC)


class DroneView(APIView):
    authentication_classes = [DroneAuthentication]
    permission_classes = [IsDrone]


class CollectOfferView(DroneView):
    @extend_schema(request=OfferSerializer, responses={200: UPLOAD, 201: UPLOAD})
    def post(self, request: Request) -> Response:
        """Offer a log: its upload, new or the one under way or stored (same bytes)."""
        body = OfferSerializer(data=request.data)
        body.is_valid(raise_exception=True)
        data = body.validated_data
        wanted = collection.Offer(
            kind=data["kind"],
            name=data["name"],
            size=data["size"],
            sha256=data["sha256"],
            flight_started_at=_epoch(data["flight_start"]),
            flight_ended_at=_epoch(data["flight_end"]),
        )
        try:
            row = collection.offer(request.auth, wanted)
        except collection.CollectionRefused as exc:
            return _refusal(exc)
        fresh = row.received == 0 and row.completed_at is None
        return Response(
            collection.describe(row),
            status=status.HTTP_201_CREATED if fresh else status.HTTP_200_OK,
        )


class CollectChunkView(DroneView):
    parser_classes = [OctetStreamParser]

    @extend_schema(
        request={"application/octet-stream": bytes},
        responses={200: UPLOAD},
        description="Bytes at `?offset=` (the `received` of the last answer); 409 with the "
        "expected `received` when the offset is not it.",
    )
    def put(self, request: Request, upload_id: str) -> Response:
        try:
            offset = int(request.query_params.get("offset", ""))
        except ValueError:
            raise exceptions.ValidationError({"offset": ["Give the chunk's offset."]}) from None
        data = request.data if isinstance(request.data, bytes) else b""
        try:
            row = collection.receive(request.auth, upload_id, offset, data)
        except collection.CollectionRefused as exc:
            return _refusal(exc)
        return Response(collection.describe(row))

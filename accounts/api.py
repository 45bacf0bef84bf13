"""`POST /api/v1/token/`: a username and password (and a one-time code once the user has
a second factor) for a named, expiring personal token bound to one organisation; the caller's own tokens listed
(`GET /api/v1/tokens/`) and revoked (`DELETE /api/v1/tokens/{id}/`)."""

from __future__ import annotations

from django.contrib.auth import authenticate
from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import exceptions, serializers
from rest_framework.decorators import (
    api_view,
    authentication_classes,
    permission_classes,
    throttle_classes,
)
from rest_framework.permissions import AllowAny
from rest_framework.request import Request
from rest_framework.response import Response

from config.api import StrictSerializer
from fleet.models import Membership, Organisation

from . import tokens, twofactor
from .errors import Refused
from .models import ApiToken
from .throttling import AuthRateThrottle


class TokenRequestSerializer(StrictSerializer):
    username = serializers.CharField()
    password = serializers.CharField(style={"input_type": "password"}, trim_whitespace=False)
    name = serializers.CharField(required=False, allow_blank=True, max_length=80)
    expires_in_days = serializers.IntegerField(required=False, min_value=1)
    expires_at = serializers.DateTimeField(required=False)
    scope = serializers.ChoiceField(choices=[*tokens.READ_ALIASES, "operate"], required=False)
    otp = serializers.CharField(required=False, allow_blank=True, max_length=16)
    organisation = serializers.SlugField(required=False, allow_blank=True)


TokenSerializer = inline_serializer(
    "Token",
    {
        "token": serializers.CharField(),
        "name": serializers.CharField(),
        "scope": serializers.CharField(),
        "organisation": serializers.CharField(),
        "expires_at": serializers.DateTimeField(),
    },
)


def token_body(issued: tokens.Issued) -> dict:
    return {
        "token": issued.key,
        "name": issued.token.name,
        "scope": issued.token.scope,
        "organisation": issued.token.organisation.slug if issued.token.organisation else None,
        "expires_at": issued.token.expires_at.isoformat(),
    }


def _second_factor(user: object, code: object) -> None:
    """A user with an authenticator gives its code (`otp`); one whose organisation
    requires a second factor and who has none gets no token until they enrol."""
    device = twofactor.device_of(user)
    if device is not None:
        if not twofactor.check(device, code):
            raise exceptions.AuthenticationFailed(
                "otp: the current code of your authenticator app is required.", code="otp_required"
            )
    elif twofactor.required_for(user):
        raise exceptions.PermissionDenied(
            "Your organisation requires a second factor: set it up on your security page first.",
            code="second_factor_required",
        )


def _organisation_for(user: object, slug: str) -> Organisation:
    """The one organisation a new token acts for: `organisation` (the slug of one of the
    user's), or the user's only one; a member of several must name it."""
    memberships = Membership.objects.for_user(user)
    if slug:
        found = memberships.filter(organisation__slug=slug).first()
        if found is None:
            raise exceptions.ValidationError({"organisation": ["not an organisation of yours"]})
        return found.organisation
    found = list(memberships[:2])
    if len(found) != 1:
        raise exceptions.ValidationError(
            {"organisation": ["name the organisation the token acts for (its slug)"]}
        )
    return found[0].organisation


@extend_schema(request=TokenRequestSerializer, responses=TokenSerializer, auth=[])
@api_view(["POST"])
@authentication_classes([])
@permission_classes([AllowAny])
@throttle_classes([AuthRateThrottle])
def obtain_token(request: Request) -> Response:
    """Exchange a username and password (and `otp`, the authenticator's code, once the
    user has one) for a new personal API token (header `Authorization: Token …`), named,
    expiring after `expires_in_days` (default API_TOKEN_DEFAULT_DAYS), `operate` unless
    `scope` is `read`. The token acts in one organisation only: `organisation` (a slug),
    which a member of several must give."""
    serializer = TokenRequestSerializer(data=request.data)
    serializer.is_valid(raise_exception=True)
    data = serializer.validated_data
    user = authenticate(
        request=request._request, username=data["username"], password=data["password"]
    )
    if user is None or not user.is_active:
        raise exceptions.AuthenticationFailed("Unable to log in with the provided credentials.")
    _second_factor(user, data.get("otp"))
    organisation = _organisation_for(user, data.get("organisation", ""))
    try:
        issued = tokens.issue(
            user,
            organisation=organisation,
            name=data.get("name"),
            days=data.get("expires_in_days"),
            expires_at=data.get("expires_at"),
            scope=data.get("scope"),
        )
    except Refused as exc:
        raise exceptions.ValidationError({exc.field: [exc.message]}) from None
    return Response(token_body(issued))


class ApiTokenSerializer(serializers.ModelSerializer):
    organisation = serializers.SlugRelatedField(slug_field="slug", read_only=True)

    class Meta:
        model = ApiToken
        fields = [
            "id",
            "name",
            "prefix",
            "scope",
            "organisation",
            "created_at",
            "expires_at",
            "last_used_at",
            "revoked_at",
            "state",
        ]


@extend_schema(responses=ApiTokenSerializer(many=True))
@api_view(["GET"])
def my_tokens(request: Request) -> Response:
    """The caller's own personal tokens (never their keys), newest first."""
    return Response(ApiTokenSerializer(tokens.tokens_of(request.user), many=True).data)


@extend_schema(request=None, responses={204: None})
@api_view(["DELETE"])
def revoke_my_token(request: Request, pk: int) -> Response:
    """Revoke one of the caller's tokens (another user's answers 404)."""
    token = ApiToken.objects.filter(pk=pk, user=request.user).first()
    if token is None:
        raise exceptions.NotFound("No such token of yours.")
    tokens.revoke(token)
    return Response(status=204)

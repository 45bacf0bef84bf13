"""How the API knows who calls: the session (portal pages) or `Authorization: Token <key>`.

Token refusals say why (revoked, expired) with 401; a read-only token asking to change
anything gets 403 `read_only_token`; a session whose user must use a second factor and
has not gets 403 `second_factor_required` for anything but reading. Both are enforced
here, at authentication, so they hold for every view, including those with their own
permission classes. Tokens are not asked for a code on each request: a token is only
issued after one (accounts/api.py) or from a session that gave one. A token made for one
organisation binds the request to it (fleet.tenancy.reach): another organisation's
drones, missions, telemetry and logs are as unknown to it as to an outsider (404).
"""

from __future__ import annotations

from typing import Any

from django.utils import timezone
from rest_framework import authentication, exceptions
from rest_framework.permissions import SAFE_METHODS

from fleet import tenancy

from . import tokens, twofactor
from .models import ApiToken


class TokenAuthentication(authentication.TokenAuthentication):
    """Personal tokens (`sky_…`), and DRF's older tokens until they expire."""

    def authenticate(self, request: Any) -> tuple[Any, Any] | None:
        result = super().authenticate(request)
        if result is None:
            return None
        token = result[1]
        if request.method not in SAFE_METHODS and isinstance(token, ApiToken) and token.read_only:
            raise exceptions.PermissionDenied(
                "This token is read-only; use an operate token to change anything.",
                code="read_only_token",
            )
        return result

    def authenticate_credentials(self, key: str) -> tuple[Any, Any]:
        if key.startswith(tokens.PREFIX):
            token = tokens.find(key)
            refused = tokens.refusal(token)
            if refused:
                code, message = refused
                raise exceptions.AuthenticationFailed(message, code=code)
            tokens.touch(token)  # type: ignore[arg-type]
            if token.organisation_id is not None:  # type: ignore[union-attr]
                # Every for_user lookup of this request now reaches that organisation only.
                tenancy.bind(token.user, token.organisation_id)  # type: ignore[union-attr]
            return token.user, token  # type: ignore[union-attr]
        user, legacy = super().authenticate_credentials(key)
        if tokens.legacy_expiry(legacy) <= timezone.now():
            raise exceptions.AuthenticationFailed(
                "This token has expired; create a new one.", code="token_expired"
            )
        return user, legacy


class SessionAuthentication(authentication.SessionAuthentication):
    """DRF's session authentication (with its CSRF check), refusing changes from a
    session that still owes the second factor its organisation requires."""

    def authenticate(self, request: Any) -> tuple[Any, Any] | None:
        result = super().authenticate(request)
        if result and request.method not in SAFE_METHODS and twofactor.missing(request._request):
            raise exceptions.PermissionDenied(
                "Your organisation requires a second factor: set up your authenticator "
                "app on your security page and sign in with it.",
                code="second_factor_required",
            )
        return result

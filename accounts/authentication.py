"""How the API knows who calls: the session (portal pages) or `Authorization: Token <key>`.

Token refusals say why (revoked, expired) with 401; a read-only token asking to change
anything gets 403 `read_only_token`. The scope is enforced here, at authentication, so
it holds for every view, including those with their own permission classes.
"""

from __future__ import annotations

from typing import Any

from django.utils import timezone
from rest_framework import authentication, exceptions
from rest_framework.permissions import SAFE_METHODS

from . import tokens
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
            return token.user, token  # type: ignore[union-attr]
        user, legacy = super().authenticate_credentials(key)
        if tokens.legacy_expiry(legacy) <= timezone.now():
            raise exceptions.AuthenticationFailed(
                "This token has expired; create a new one.", code="token_expired"
            )
        return user, legacy

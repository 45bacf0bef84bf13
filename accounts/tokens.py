"""Personal API tokens: issue, find, refuse, revoke.

A key is `sky_` and 32 random bytes; the database keeps its SHA-256 only. A fast hash is
enough for keys that random and lets each request find its token through one index.
Tokens made by DRF's own `Token` model before these existed are still accepted, with the
same operate scope, until API_TOKEN_DEFAULT_DAYS after they were made.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.utils import timezone
from django.utils.dateparse import parse_datetime
from rest_framework.authtoken.models import Token as LegacyToken

from fleet import compiled

from . import audit
from .errors import Refused
from .models import ApiToken

PREFIX = "sky_"
# last_used_at is written at most this often per token, not on every request.
TOUCH_EVERY = timedelta(seconds=60)


def _bad(field: str, message: str) -> Refused:
    return Refused(message, 400, field)


@dataclass(frozen=True)
class Issued:
    token: ApiToken
    key: str  # shown to the user once, never stored


def digest(key: str) -> str:
    return hashlib.sha256(key.encode()).hexdigest()


# Spellings of the read-only scope accepted on input (stored as `read`).
READ_ALIASES = ("read", "read-only", "read_only", "readonly")


def _scope(scope: Any) -> str:
    scope = str(scope or ApiToken.Scope.OPERATE).strip().lower()
    if scope in READ_ALIASES:
        return ApiToken.Scope.READ
    if scope != ApiToken.Scope.OPERATE:
        raise _bad("scope", "must be read (read-only) or operate")
    return scope


def _expiry(days: Any, expires_at: Any) -> datetime:
    """When the token expires: `expires_at` (a datetime or ISO 8601 text) or `days`
    from now (default API_TOKEN_DEFAULT_DAYS), within API_TOKEN_MAX_DAYS."""
    now, longest = timezone.now(), settings.API_TOKEN_MAX_DAYS
    if expires_at not in (None, ""):
        when = expires_at if isinstance(expires_at, datetime) else parse_datetime(str(expires_at))
        if when is None:
            raise _bad("expires_at", "must be an ISO 8601 date and time")
        when = when if timezone.is_aware(when) else timezone.make_aware(when)
        if not now < when <= now + timedelta(days=longest):
            raise _bad("expires_at", f"must be in the next {longest} days")
        return when
    if days in (None, ""):
        days = settings.API_TOKEN_DEFAULT_DAYS
    try:
        days = int(days)
    except (TypeError, ValueError):
        raise _bad("expires_in_days", "must be a whole number of days") from None
    if not 1 <= days <= longest:
        raise _bad("expires_in_days", f"must be 1 to {longest}")
    return now + timedelta(days=days)


def issue(
    user: Any,
    *,
    name: Any = None,
    days: Any = None,
    scope: Any = None,
    organisation: Any = None,
    expires_at: Any = None,
) -> Issued:
    """A new token for `user`; raises Refused for a bad name, expiry or scope."""
    name = str(name or "").strip() or f"API token {timezone.now():%Y-%m-%d %H:%M}"
    if len(name) > 80:
        raise _bad("name", "at most 80 characters")
    expiry, scope = _expiry(days, expires_at), _scope(scope)
    key = PREFIX + secrets.token_urlsafe(32)
    token = ApiToken.objects.create(
        user=user,
        organisation=organisation,
        name=name,
        scope=scope,
        key_hash=digest(key),
        prefix=key[: len(PREFIX) + 6],
        expires_at=expiry,
    )
    _audit(token, "token.create", actor=user)
    return Issued(token, key)


def _audit(token: ApiToken, action: str, actor: Any = None) -> None:
    """Token changes go to the token's organisation, or to every organisation of its
    user when it acts for all of them."""
    where = token.organisation_id or audit.organisation_ids_of(token.user)
    audit.record(
        where,
        audit.Kind.TOKEN,
        action,
        target=f"{token.name} ({token.prefix}…) of {token.user.get_username()}",
        actor=actor,
        detail={"scope": token.scope, "expires_at": token.expires_at.isoformat()},
    )


# What the token lookup is compiled with in place of a key's digest (fleet.compiled): a
# text no SHA-256 digest is.
_DIGEST_STAND_IN = "stand-in: not a digest"


def _compile_find(shape: object = None) -> compiled.Compiled:
    queryset = ApiToken.objects.select_related("user").filter(key_hash=_DIGEST_STAND_IN)
    return compiled.Compiled(queryset[:1], {"digest": _DIGEST_STAND_IN})


# Every request made with a token looks it up: its SQL is built once.
_FIND = compiled.Shapes(_compile_find)


def find(key: str) -> ApiToken | None:
    """The token with this key, with its user (one statement)."""
    return _FIND[None].first(digest=digest(key))  # type: ignore[return-value]


def refusal(token: ApiToken | None) -> tuple[str, str] | None:
    """(code, message) saying why the token may not be used, or None if it may."""
    if token is None or not token.user.is_active:
        return "token_invalid", "Invalid token."
    if token.revoked_at is not None:
        return "token_revoked", "This token was revoked; create a new one on your security page."
    if token.expires_at <= timezone.now():
        when = f"{token.expires_at:%Y-%m-%d %H:%M} UTC"
        return "token_expired", f"This token expired on {when}; create a new one."
    return None


def touch(token: ApiToken) -> None:
    now = timezone.now()
    if token.last_used_at is None or now - token.last_used_at > TOUCH_EVERY:
        ApiToken.objects.filter(pk=token.pk).update(last_used_at=now)


def legacy_expiry(token: LegacyToken) -> datetime:
    return token.created + timedelta(days=settings.API_TOKEN_DEFAULT_DAYS)


def revoke(token: ApiToken) -> bool:
    """Revoke an active token; False if it was already revoked."""
    done = ApiToken.objects.filter(pk=token.pk, revoked_at__isnull=True).update(
        revoked_at=timezone.now()
    )
    if done:
        _audit(token, "token.revoke")
    return bool(done)


def revoke_for_organisation(user: Any, organisation: Any) -> int:
    """Revoke what `user` holds for `organisation` on leaving it: the tokens made for it,
    and the older unnamed token (it cannot be told apart by organisation)."""
    count = ApiToken.objects.filter(
        user=user, organisation=organisation, revoked_at__isnull=True
    ).update(revoked_at=timezone.now())
    return count + revoke_legacy(user)


def tokens_of(user: Any) -> list[ApiToken]:
    return list(ApiToken.objects.filter(user=user).select_related("organisation")[:100])


def legacy_tokens_of(user: Any) -> list[dict]:
    """The user's older DRF token, if any, with its expiry (for the security page)."""
    return [
        {"created": t.created, "expires_at": legacy_expiry(t), "prefix": t.key[:6]}
        for t in LegacyToken.objects.filter(user=user)
    ]


def revoke_legacy(user: Any) -> int:
    deleted, _ = LegacyToken.objects.filter(user=user).delete()
    if deleted:
        audit.record(
            audit.organisation_ids_of(user),
            audit.Kind.TOKEN,
            "token.revoke",
            target=f"older unnamed token of {user.get_username()}",
        )
    return deleted

"""Portal pages of the accounts app: the user's own security page and its tokens."""

from __future__ import annotations

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_POST

from . import tokens
from .errors import Refused
from .models import ApiToken


def _security_context(request: HttpRequest) -> dict:
    return {
        "tokens": tokens.tokens_of(request.user),
        "legacy_tokens": tokens.legacy_tokens_of(request.user),
        "scopes": ApiToken.Scope.choices,
        "default_days": settings.API_TOKEN_DEFAULT_DAYS,
        "max_days": settings.API_TOKEN_MAX_DAYS,
    }


@login_required
def security(request: HttpRequest) -> HttpResponse:
    """The user's own security page: tokens (and, with sign-in, its history and 2FA)."""
    return render(request, "accounts/security.html", _security_context(request))


@login_required
@require_POST
def create_token(request: HttpRequest) -> HttpResponse:
    """A new token, its key shown on this response only (it is not stored)."""
    try:
        issued = tokens.issue(
            request.user,
            name=request.POST.get("name"),
            days=request.POST.get("expires_in_days"),
            scope=request.POST.get("scope"),
            organisation=getattr(request, "organisation", None),
        )
    except Refused as exc:
        context = {**_security_context(request), "token_error": f"{exc.field}: {exc.message}"}
        return render(request, "accounts/security.html", context, status=400)
    context = {**_security_context(request), "new_key": issued.key, "new_token": issued.token}
    return render(request, "accounts/security.html", context, status=201)


@login_required
@require_POST
def revoke_token(request: HttpRequest, pk: int) -> HttpResponse:
    token = get_object_or_404(ApiToken, pk=pk, user=request.user)
    if tokens.revoke(token):
        messages.success(request, f"Token “{token.name}” revoked.")
    return redirect("accounts:security")


@login_required
@require_POST
def revoke_legacy_token(request: HttpRequest) -> HttpResponse:
    if tokens.revoke_legacy(request.user):
        messages.success(request, "The older unnamed token was revoked.")
    return redirect("accounts:security")

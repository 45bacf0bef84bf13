"""Portal pages of the accounts app: the user's own security page (tokens, sign-ins,
second factor) and password reset."""

from __future__ import annotations

import django_otp
from django.conf import settings
from django.contrib import messages
from django.contrib.auth import views as auth_views
from django.contrib.auth.decorators import login_required
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse_lazy
from django.views.decorators.http import require_POST

from config.throttling import LoginAttempts, parse_rate
from fleet.tenancy import acting_organisation

from . import signin, tokens, twofactor
from .errors import Refused
from .models import ApiToken


def _security_context(request: HttpRequest) -> dict:
    return {
        "tokens": tokens.tokens_of(request.user),
        "legacy_tokens": tokens.legacy_tokens_of(request.user),
        "scopes": ApiToken.Scope.choices,
        "default_days": settings.API_TOKEN_DEFAULT_DAYS,
        "max_days": settings.API_TOKEN_MAX_DAYS,
        "attempts": signin.recent_attempts(request.user),
        "has_second_factor": twofactor.device_of(request.user) is not None,
        "second_factor_required": twofactor.required_for(request.user),
        "login_limit": parse_rate(settings.LOGIN_RATE),
    }


@login_required
def security(request: HttpRequest) -> HttpResponse:
    """The user's own security page: tokens (and, with sign-in, its history and 2FA)."""
    return render(request, "accounts/security.html", _security_context(request))


@login_required
@require_POST
def create_token(request: HttpRequest) -> HttpResponse:
    """A new token, its key shown on this response only (it is not stored). A session
    that owes the second factor its organisation requires mints no credential."""
    if twofactor.missing(request):
        error = "second factor: your organisation requires it; set it up and sign in with it first."
        context = {**_security_context(request), "token_error": error}
        return render(request, "accounts/security.html", context, status=403)
    try:
        issued = tokens.issue(
            request.user,
            name=request.POST.get("name"),
            days=request.POST.get("expires_in_days"),
            scope=request.POST.get("scope"),
            organisation=acting_organisation(request),
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


@login_required
def two_factor(request: HttpRequest) -> HttpResponse:
    """Enrol an authenticator app, or move to another: scan the QR code, then confirm
    with its first code, after proving the current one (or the password)."""
    device = twofactor.pending_enrolment(request.user) or twofactor.start_enrolment(request.user)
    status, error = 200, None
    if request.method == "POST":
        status, error = _enrol(request, device)
        if error is None:
            django_otp.login(request, device)  # this session has now given a code
            messages.success(request, "Two-factor sign-in is on.")
            return redirect("accounts:security")
    context = {
        "qr": twofactor.qr_svg(device),
        "secret": twofactor.secret_of(device),
        "error": error,
        "has_second_factor": twofactor.device_of(request.user) is not None,
    }
    return render(request, "accounts/two_factor.html", context, status=status)


def _enrol(request: HttpRequest, device: object) -> tuple[int, str | None]:
    """(status, None) once the new authenticator is on; otherwise why not. Wrong
    passwords count against the LOGIN_RATE limit like those on the sign-in page."""
    attempts = LoginAttempts(request)
    if attempts.exhausted():
        return 429, "Too many failed attempts; try again in a minute."
    if not twofactor.current_proof(request.user, request.POST):
        attempts.failed()
        return 403, "Give the code your current app shows (with none set up: your password)."
    if not twofactor.confirm(request.user, device, request.POST.get("code")):
        return 400, "That code is not right; enter the one your app shows now."
    return 302, None


@login_required
@require_POST
def disable_two_factor(request: HttpRequest) -> HttpResponse:
    device = twofactor.device_of(request.user)
    if device is None:
        return redirect("accounts:security")
    if twofactor.required_for(request.user):
        messages.error(request, "Your organisation requires a second factor; it stays on.")
    elif not twofactor.check(device, request.POST.get("code")):
        messages.error(request, "That code is not right; two-factor sign-in stays on.")
    else:
        twofactor.disable(request.user)
        messages.success(request, "Two-factor sign-in is off.")
    return redirect("accounts:security")


class PasswordResetView(auth_views.PasswordResetView):
    """Django's reset-by-e-mail page; requests count against the LOGIN_RATE limit per
    address, so it cannot be used to flood mailboxes."""

    email_template_name = "registration/password_reset_email.txt"
    subject_template_name = "registration/password_reset_subject.txt"
    success_url = reverse_lazy("accounts:password_reset_done")

    def post(self, request: HttpRequest, *args: object, **kwargs: object) -> HttpResponse:
        attempts = LoginAttempts(request)
        if attempts.exhausted():
            context = self.get_context_data(form=self.get_form(), throttled=True)
            return self.render_to_response(context, status=429)
        attempts.failed()
        return super().post(request, *args, **kwargs)


class PasswordResetConfirmView(auth_views.PasswordResetConfirmView):
    success_url = reverse_lazy("accounts:password_reset_complete")

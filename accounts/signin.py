"""Signing in: password, then a one-time code for users with an authenticator.

Failed attempts are limited by the LOGIN_RATE throttle (accounts/throttling.py, counting
with config.throttling.LoginAttempts): per client address and per username, over the
limit further tries are refused with 429 until the window ends (a lock-out that lifts by
itself, so nobody can lock a colleague out for good). Every attempt is kept for the
user's own security page.
"""

from __future__ import annotations

import time
from datetime import timedelta
from typing import Any

import django_otp
from django.conf import settings
from django.contrib.auth import get_user_model, login, user_login_failed
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.urls import reverse
from django.utils import timezone
from django.utils.http import url_has_allowed_host_and_scheme

from config.throttling import LoginAttempts, client_address

from . import twofactor
from .models import SignInAttempt
from .throttling import LoginView as ThrottledLoginView

PENDING = "accounts_pending_sign_in"
# A password accepted pending its code is forgotten after this long.
PENDING_S = 300


class LoginView(ThrottledLoginView):
    """Django's login page with the LOGIN_RATE limit; users with an authenticator are
    signed in only after their code (accounts:login_code)."""

    def form_valid(self, form):  # type: ignore[no-untyped-def]
        user = form.get_user()
        if twofactor.device_of(user) is None:
            return super().form_valid(form)
        self.request.session[PENDING] = {
            "user": user.pk,
            "backend": user.backend,
            "next": self.get_success_url(),
            "until": time.time() + PENDING_S,
        }
        return redirect("accounts:login_code")


def _pending_user(request: HttpRequest) -> tuple[Any, dict] | None:
    pending = request.session.get(PENDING)
    if not pending or pending.get("until", 0) < time.time():
        return None
    user = get_user_model().objects.filter(pk=pending["user"], is_active=True).first()
    return (user, pending) if user else None


def login_code(request: HttpRequest) -> HttpResponse:
    """The second step: the code from the user's authenticator app."""
    found = _pending_user(request)
    if found is None:
        return redirect("login")
    user, pending = found
    if request.method != "POST":
        return render(request, "registration/login_code.html")
    attempts = LoginAttempts(request)
    if attempts.exhausted():
        message = "Too many failed attempts; try again in a minute."
        return render(request, "registration/login_code.html", {"error": message}, status=429)
    device = twofactor.device_of(user)
    if device is None or not twofactor.check(device, request.POST.get("code")):
        attempts.failed()
        user_login_failed.send(
            sender=__name__, credentials={"username": user.get_username()}, request=request
        )
        error = "That code is not right (or was used already); try the next one."
        return render(request, "registration/login_code.html", {"error": error}, status=400)
    del request.session[PENDING]
    request.second_factor = True  # type: ignore[attr-defined]
    login(request, user, backend=pending["backend"])
    django_otp.login(request, device)
    target = pending.get("next") or ""
    if not url_has_allowed_host_and_scheme(target, {request.get_host()}):
        target = reverse("fleet:index")
    return redirect(target)


# -- the record of attempts (signal receivers) -------------------------------------------


def _attempt(request: HttpRequest | None, **fields: Any) -> None:
    """Keep one attempt; those older than SIGN_IN_HISTORY_DAYS go."""
    meta = getattr(request, "META", {}) if request is not None else {}
    SignInAttempt.objects.create(
        ip=client_address(request) if meta.get("REMOTE_ADDR") else None,
        user_agent=str(meta.get("HTTP_USER_AGENT", ""))[:200],
        **fields,
    )
    cutoff = timezone.now() - timedelta(days=settings.SIGN_IN_HISTORY_DAYS)
    SignInAttempt.objects.filter(at__lt=cutoff).delete()


def signed_in(sender: Any, request: HttpRequest | None, user: Any, **kwargs: Any) -> None:
    by_code = bool(getattr(request, "second_factor", False))
    _attempt(
        request,
        user=user,
        username=user.get_username(),
        succeeded=True,
        method="password and one-time code" if by_code else "password",
    )


def sign_in_failed(
    sender: Any, credentials: dict, request: HttpRequest | None = None, **kw: Any
) -> None:
    username = str(credentials.get("username", ""))[:150]
    _attempt(
        request,
        user=get_user_model().objects.filter(username=username).first(),
        username=username,
        succeeded=False,
        method="one-time code" if sender == __name__ else "password",
    )


def recent_attempts(user: Any, limit: int = 20) -> list[SignInAttempt]:
    return list(SignInAttempt.objects.filter(user=user)[:limit])

"""The people's sign-in limits: the API token view's throttle and the throttled login page.

They live in accounts because only accounts' own views use them (the token view in
accounts/api.py, the sign-in page in accounts/signin.py), and no other app may import
accounts. What they build on is shared and stays in config/throttling.py: the rate
format, the client's address, and the failed-sign-in counts a drone's sign-in
(logs/collect_api.py) keeps as a person's do.
"""

from __future__ import annotations

from django.conf import settings
from django.contrib.auth import views as auth_views
from django.http import HttpRequest, HttpResponse
from rest_framework.throttling import SimpleRateThrottle

from config.throttling import LoginAttempts


class AuthRateThrottle(SimpleRateThrottle):
    """`POST /api/v1/token/`: AUTH_TOKEN_RATE requests per client address."""

    scope = "auth"

    def get_rate(self) -> str:
        return settings.AUTH_TOKEN_RATE

    def get_cache_key(self, request, view) -> str:  # type: ignore[no-untyped-def]
        return self.cache_format % {"scope": self.scope, "ident": self.get_ident(request)}


class LoginView(auth_views.LoginView):
    """Django's login page, refusing with 429 while the caller's failures are over the
    limit, so a password cannot be guessed faster than LOGIN_RATE."""

    def post(self, request: HttpRequest, *args, **kwargs) -> HttpResponse:  # type: ignore[no-untyped-def]
        attempts = LoginAttempts(request)
        if attempts.exhausted():
            message = "Too many failed logins; try again in a minute."
            context = self.get_context_data(form=self.get_form(), throttled=message)
            return self.render_to_response(context, status=429)
        return super().post(request, *args, **kwargs)

    def form_invalid(self, form):  # type: ignore[no-untyped-def]
        # Only refused credentials count: a password accepted pending a second
        # factor (accounts.signin) is not a failure.
        LoginAttempts(self.request).failed()
        return super().form_invalid(form)

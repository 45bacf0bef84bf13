"""The OpenAPI schema describes the session authentication as DRF's own (a cookie)."""

from drf_spectacular.authentication import SessionScheme


class AccountsSessionScheme(SessionScheme):
    target_class = "accounts.authentication.SessionAuthentication"

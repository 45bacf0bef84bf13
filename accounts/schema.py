"""The OpenAPI schema describes the session authentication as DRF's own (a cookie).

The class registers itself with drf-spectacular when this module is imported: config/urls.py
imports it beside the schema's views, so processes that serve no URL (workers, the gateway)
never load the schema generator (0.065 s of CPU at every start)."""

from drf_spectacular.authentication import SessionScheme


class AccountsSessionScheme(SessionScheme):
    target_class = "accounts.authentication.SessionAuthentication"

"""The lookups on every command's path are prepared once per connection: PostgreSQL plans
them once, not on every call (fleet.compiled)."""

import pytest
from django.db import connection

from accounts import tokens
from fleet.models import Role
from tests import factories

pytestmark = pytest.mark.django_db


def _prepared() -> list[str]:
    with connection.cursor() as cursor:
        cursor.execute("SELECT statement FROM pg_prepared_statements")
        return [row[0] for row in cursor.fetchall()]


def test_a_token_lookup_is_prepared_on_its_connection_and_still_finds_the_token():
    org = factories.organisation("acme")
    user = factories.person(org, Role.ADMIN, "owner")
    issued = tokens.issue(user, name="ci")
    key = issued.key
    assert tokens.find(key).pk == issued.token.pk
    assert tokens.find(key + "x") is None
    assert any('"accounts_apitoken"' in statement for statement in _prepared())


def test_djangos_own_queries_are_not_prepared():
    org = factories.organisation("acme")
    list(type(org).objects.filter(slug="acme"))
    assert not any('"fleet_organisation"' in statement for statement in _prepared())

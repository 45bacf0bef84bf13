"""Password guessing is slowed down (accounts/throttling.py): the token view and the login
page count per client address (and the login page per username too) in the shared Redis
cache."""

import uuid

import pytest
from django.contrib.auth.models import User
from django.test import Client
from rest_framework.test import APIClient

PASSWORD = "correct horse battery staple"


def address() -> str:
    """An address of its own per call: the counts outlive a test in the shared Redis."""
    return f"2001:db8::{uuid.uuid4().hex[:4]}:{uuid.uuid4().hex[:4]}"


@pytest.fixture
def rates(settings):
    settings.AUTH_TOKEN_RATE = "10/min"
    settings.LOGIN_RATE = "10/min"


@pytest.fixture
def user(db):
    # A member of one organisation: a token is made for one (accounts/api.py).
    from tests import factories

    return factories.person(factories.organisation(), username=f"pilot-{uuid.uuid4().hex[:8]}")


def token(client: APIClient, ip: str, username: str, password: str, **headers: str):  # type: ignore[no-untyped-def]
    body = {"username": username, "password": password}
    return client.post("/api/v1/token/", body, format="json", REMOTE_ADDR=ip, **headers)


def test_wrong_token_requests_are_refused_with_429_after_the_limit(rates, user):
    client, guesser = APIClient(), address()
    codes = [token(client, guesser, user.username, f"guess-{n}").status_code for n in range(50)]
    assert codes[:10] == [403] * 10  # refused credentials
    assert codes[10:] == [429] * 40
    refused = token(client, guesser, user.username, PASSWORD)
    assert refused.status_code == 429 and refused.json()["code"] == "throttled"
    # A forged X-Forwarded-For is not believed (NUM_PROXIES is 0).
    forged = token(client, guesser, user.username, PASSWORD, HTTP_X_FORWARDED_FOR=address())
    assert forged.status_code == 429

    elsewhere = token(client, address(), user.username, PASSWORD)
    assert elsewhere.status_code == 200 and elsewhere.json()["token"]


def login(ip: str, username: str, password: str):  # type: ignore[no-untyped-def]
    body = {"username": username, "password": password}
    return Client().post("/accounts/login/", body, REMOTE_ADDR=ip)


def test_failed_logins_are_refused_per_address(rates, user, db):
    other = User.objects.create_user(f"pilot-{uuid.uuid4().hex[:8]}", password=PASSWORD)
    guesser = address()
    names = [f"nobody-{n}-{uuid.uuid4().hex[:6]}" for n in range(10)]
    assert [login(guesser, name, "wrong").status_code for name in names] == [200] * 10
    refused = login(guesser, other.username, PASSWORD)
    assert refused.status_code == 429
    assert "Too many failed logins" in refused.content.decode()
    assert "_auth_user_id" not in refused.client.session
    assert login(address(), other.username, PASSWORD).status_code == 302


def test_failed_logins_are_refused_per_username_from_any_address(rates, user):
    codes = [login(address(), user.username, "wrong").status_code for _ in range(10)]
    assert codes == [200] * 10
    assert login(address(), user.username, PASSWORD).status_code == 429


def test_a_successful_login_does_not_count(rates, user):
    ip = address()
    assert [login(ip, user.username, PASSWORD).status_code for _ in range(12)] == [302] * 12

"""Personal API tokens: named, expiring, read-only or operate, stored hashed, revocable."""

from __future__ import annotations

from datetime import timedelta

from django.test import Client
from django.utils import timezone
from rest_framework.authtoken.models import Token
from rest_framework.test import APIClient

from accounts import tokens
from accounts.models import ApiToken

PASSWORD = "correct horse battery staple"
COMMAND = {"command": "arm", "params": {}}


def api(key: str) -> APIClient:
    return APIClient(HTTP_AUTHORIZATION=f"Token {key}")


def command(key: str):  # type: ignore[no-untyped-def]
    return api(key).post("/api/v1/drones/ACME_1/commands/", COMMAND, format="json")


def test_the_token_endpoint_issues_a_named_expiring_token_stored_hashed(world):
    response = APIClient().post(
        "/api/v1/token/",
        {"username": "operator", "password": PASSWORD, "name": "survey", "expires_in_days": 7},
        format="json",
    )
    assert response.status_code == 200
    body = response.json()
    key = body["token"]
    assert body["name"] == "survey" and body["scope"] == "operate"
    token = ApiToken.objects.get(user=world.operator)
    assert token.key_hash == tokens.digest(key) and key not in token.key_hash
    assert timedelta(days=6, hours=23) < token.expires_at - timezone.now() <= timedelta(days=7)
    assert api(key).get("/api/v1/me/").json()["username"] == "operator"


def test_the_token_endpoint_defaults_to_the_configured_expiry_and_issues_one_per_request(
    world, settings
):
    settings.API_TOKEN_DEFAULT_DAYS = 30
    body = {"username": "viewer", "password": PASSWORD}
    first = APIClient().post("/api/v1/token/", body, format="json").json()["token"]
    second = APIClient().post("/api/v1/token/", body, format="json").json()["token"]
    assert first != second
    assert ApiToken.objects.filter(user=world.viewer).count() == 2
    token = ApiToken.objects.filter(user=world.viewer).first()
    assert timedelta(days=29) < token.expires_at - timezone.now() <= timedelta(days=30)


def test_a_bad_expiry_or_scope_is_refused_by_name_and_no_token_is_made(world, settings):
    for extra, field in (
        ({"expires_in_days": 10_000}, "expires_in_days"),
        ({"scope": "x"}, "scope"),
    ):
        body = {"username": "viewer", "password": PASSWORD, **extra}
        response = APIClient().post("/api/v1/token/", body, format="json")
        assert response.status_code == 400
        assert field in response.json()["fields"]
    assert not ApiToken.objects.exists()


def test_a_read_only_token_reads_but_cannot_command(world):
    key = tokens.issue(world.operator, name="dashboard", scope="read").key
    assert api(key).get("/api/v1/drones/").status_code == 200
    response = command(key)
    assert response.status_code == 403
    assert response.json()["code"] == "read_only_token"
    assert not world.drone.commands.exists()


def test_an_operate_token_reaches_the_command_checks(world):
    key = tokens.issue(world.operator, name="script", scope="operate").key
    response = command(key)  # the drone is offline: refused by the command path, not auth
    assert response.status_code == 409
    assert "offline" in response.json()["error"]


def test_an_expired_token_is_refused_with_a_clear_401(world):
    issued = tokens.issue(world.operator, name="old", days=1)
    ApiToken.objects.filter(pk=issued.token.pk).update(
        expires_at=timezone.now() - timedelta(seconds=1)
    )
    response = api(issued.key).get("/api/v1/me/")
    assert response.status_code == 401
    body = response.json()
    assert body["code"] == "token_expired" and "expired" in body["error"]


def test_a_revoked_token_is_refused_and_an_unknown_one_is_invalid(world):
    issued = tokens.issue(world.operator, name="gone")
    assert tokens.revoke(issued.token)
    response = api(issued.key).get("/api/v1/me/")
    assert response.status_code == 401 and response.json()["code"] == "token_revoked"
    assert api(tokens.PREFIX + "nonsense").get("/api/v1/me/").status_code == 401


def test_older_drf_tokens_work_until_their_expiry(world, settings):
    settings.API_TOKEN_DEFAULT_DAYS = 90
    fresh = Token.objects.create(user=world.viewer)
    assert api(fresh.key).get("/api/v1/me/").status_code == 200
    Token.objects.filter(pk=fresh.pk).update(created=timezone.now() - timedelta(days=91))
    response = api(fresh.key).get("/api/v1/me/")
    assert response.status_code == 401 and response.json()["code"] == "token_expired"


def test_the_security_page_creates_lists_and_revokes_tokens(world):
    client = Client()
    client.force_login(world.operator)
    response = client.post(
        "/accounts/security/tokens/",
        {"name": "field laptop", "expires_in_days": "30", "scope": "read"},
    )
    assert response.status_code == 201
    key = response.context["new_key"]
    page = response.content.decode()
    assert key in page and "field laptop" in page and "Read-only" in page
    token = ApiToken.objects.get(user=world.operator)
    assert token.organisation == world.org
    # The key is shown once: the list shows only its prefix.
    listing = client.get("/accounts/security/").content.decode()
    assert "field laptop" in listing and key not in listing
    assert client.post(f"/accounts/security/tokens/{token.pk}/revoke/").status_code == 302
    assert api(key).get("/api/v1/me/").status_code == 401


def test_nobody_revokes_another_users_token(world):
    token = tokens.issue(world.operator, name="mine").token
    client = Client()
    client.force_login(world.outsider)
    assert client.post(f"/accounts/security/tokens/{token.pk}/revoke/").status_code == 404
    token.refresh_from_db()
    assert token.state == "active"


def test_a_bad_token_form_says_why_and_makes_nothing(world):
    client = Client()
    client.force_login(world.viewer)
    response = client.post("/accounts/security/tokens/", {"name": "x", "expires_in_days": "0"})
    assert response.status_code == 400
    assert "expires_in_days" in response.content.decode()
    assert not ApiToken.objects.exists()


def test_an_expiry_date_and_the_read_only_spelling_are_accepted(world):
    when = (timezone.now() + timedelta(days=3)).replace(microsecond=0)
    body = {
        "username": "viewer",
        "password": PASSWORD,
        "expires_at": when.isoformat(),
        "scope": "read-only",
    }
    response = APIClient().post("/api/v1/token/", body, format="json")
    assert response.status_code == 200, response.content
    token = ApiToken.objects.get(user=world.viewer)
    assert token.expires_at == when and token.scope == "read"
    past = {**body, "expires_at": (timezone.now() - timedelta(days=1)).isoformat()}
    refused = APIClient().post("/api/v1/token/", past, format="json")
    assert refused.status_code == 400 and "expires_at" in refused.json()["fields"]


def test_a_user_lists_and_revokes_their_tokens_through_the_api(world):
    key = tokens.issue(world.operator, name="ci", scope="operate").key
    other = tokens.issue(world.viewer, name="theirs").token
    client = api(key)
    listed = client.get("/api/v1/tokens/").json()
    assert [(t["name"], t["state"]) for t in listed] == [("ci", "active")]
    assert key not in str(listed)
    assert client.delete(f"/api/v1/tokens/{other.pk}/").status_code == 404
    assert client.delete(f"/api/v1/tokens/{listed[0]['id']}/").status_code == 204
    assert client.get("/api/v1/tokens/").status_code == 401
    # A read-only token may list but not revoke.
    read = tokens.issue(world.viewer, name="ro", scope="read").key
    assert api(read).delete(f"/api/v1/tokens/{other.pk}/").status_code == 403

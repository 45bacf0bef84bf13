"""The API's contract: one JSON error shape, strict bodies, schema and docs, tokens."""

import json

from django.test import Client
from rest_framework.authtoken.models import Token
from rest_framework.test import APIClient

PASSWORD = "correct horse battery staple"


def test_a_token_is_issued_for_good_credentials_and_works(world):
    response = APIClient().post(
        "/api/v1/token/", {"username": "viewer", "password": PASSWORD}, format="json"
    )
    assert response.status_code == 200
    token = response.json()["token"]
    client = APIClient(HTTP_AUTHORIZATION=f"Token {token}")
    assert client.get("/api/v1/me/").json()["memberships"] == [
        {"organisation": "acme", "organisation_name": "Acme", "role": "viewer"}
    ]


def test_wrong_credentials_get_a_clear_error_and_no_token(world):
    response = APIClient().post(
        "/api/v1/token/", {"username": "viewer", "password": "wrong"}, format="json"
    )
    assert response.status_code in (400, 401, 403)
    body = response.json()
    assert "credentials" in body["error"]
    assert Token.objects.count() == 0


def test_malformed_json_is_a_400_with_the_error_shape(world):
    response = APIClient().post("/api/v1/token/", data="{not json", content_type="application/json")
    assert response.status_code == 400
    body = response.json()
    assert set(body) == {"error", "code", "fields"}
    assert "JSON" in body["error"]


def test_unknown_fields_are_refused_by_name(world):
    response = APIClient().post(
        "/api/v1/token/",
        {"username": "viewer", "password": PASSWORD, "is_superuser": True},
        format="json",
    )
    assert response.status_code == 400
    assert response.json()["fields"] == {"is_superuser": ["Unknown field."]}
    assert Token.objects.count() == 0


def test_missing_fields_are_named(world):
    response = APIClient().post("/api/v1/token/", {"username": "viewer"}, format="json")
    assert response.status_code == 400
    assert "password" in response.json()["fields"]


def test_session_writes_without_csrf_token_are_refused(world):
    client = Client(enforce_csrf_checks=True)
    client.force_login(world.owner)
    response = client.post(
        "/api/v1/token/",
        data=json.dumps({"username": "owner", "password": PASSWORD}),
        content_type="application/json",
    )
    # The token endpoint takes no session, so it is CSRF-exempt by design; a session
    # endpoint must refuse. Logout through the portal is a session write:
    assert response.status_code == 200
    assert client.post("/accounts/logout/").status_code == 403


def test_the_openapi_schema_and_docs_are_served(world):
    client = Client()
    schema = client.get("/api/schema/?format=json")
    assert schema.status_code == 200
    body = schema.json()
    assert body["openapi"].startswith("3.")
    assert "/api/v1/drones/" in body["paths"]
    # The session scheme (accounts/schema.py) registered by the URL conf that serves this.
    assert {"cookieAuth", "tokenAuth"} <= set(body["components"]["securitySchemes"])
    client.force_login(world.owner)
    assert client.get("/api/docs/").status_code == 200


def test_an_absurd_page_size_is_capped_not_a_server_error(world):
    from rest_framework.test import APIClient

    client = APIClient()
    client.force_authenticate(world.owner)
    response = client.get("/api/v1/drones/", {"limit": "11682993727542969499648", "offset": "-5"})
    assert response.status_code == 200
    assert [d["drone_id"] for d in response.json()["results"]] == ["ACME_1"]

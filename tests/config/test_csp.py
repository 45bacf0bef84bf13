"""The Content-Security-Policy header on every answer: pages, errors, the API, sign-in;
what it allows and what it never does."""

from __future__ import annotations

import re

from django.test import Client

from config.csp import HEADER


def directives(response) -> dict[str, str]:  # type: ignore[no-untyped-def]
    parts = (part.strip().split(" ", 1) for part in response[HEADER].split(";"))
    return {name: value for name, value in parts}


def test_every_kind_of_answer_carries_the_policy(world):
    client = Client()
    anonymous = [client.get("/accounts/login/"), client.get("/no/such/page/")]
    client.force_login(world.owner)
    for response in (*anonymous, client.get("/fleet/"), client.get("/api/v1/alerts/")):
        policy = directives(response)
        assert policy["default-src"] == "'self'"
        assert policy["object-src"] == "'none'"
        assert policy["script-src"].startswith("'self' 'nonce-")
        assert "unsafe-inline" not in policy["script-src"]
        # Inline styles only on the API's own pages, whose bundles insert them.
        api = response.wsgi_request.path.startswith("/api/")
        assert ("unsafe-inline" in policy["style-src"]) == api
        # No style attributes elsewhere: without style-src-attr they follow style-src.
        assert "style-src-attr" not in policy
        assert "unsafe-eval" not in response[HEADER]
        assert "http" not in response[HEADER]  # no outside origin, none at all


def test_each_answer_has_its_own_nonce_and_the_import_map_carries_it(world):
    client = Client()
    client.force_login(world.owner)
    first, second = (client.get(f"/pastview/{world.drone.drone_id}/") for _ in range(2))
    nonces = [re.search(r"'nonce-([^']+)'", r[HEADER]).group(1) for r in (first, second)]
    assert nonces[0] != nonces[1] and len(nonces[0]) >= 22  # 128 random bits
    assert f'<script type="importmap" nonce="{nonces[0]}">' in first.content.decode()


def test_websockets_to_the_server_itself_are_allowed_and_nowhere_else(world):
    client = Client()
    client.force_login(world.owner)
    connect = directives(client.get("/fleet/"))["connect-src"]
    assert connect == "'self' ws://testserver wss://testserver"


def test_no_page_of_the_portal_keeps_an_inline_handler_or_script(world):
    client = Client()
    client.force_login(world.owner)
    for path in ("/fleet/", "/accounts/security/", "/api/redoc/", "/api/docs/"):
        page = client.get(path).content.decode()
        assert not re.search(r"\son[a-z]+=", page), path
        assert not re.search(r"<script(?![^>]*\ssrc=)(?![^>]*type=\"application/json\")", page)

"""`GET /control?command=objrequest` asks the drone, so it answers only to an operate API
token: a browser's cookie (a cross-site link or image carries it) and a read-only token
are refused with nothing sent. Real broker, drone and database."""

from __future__ import annotations

import pytest

from accounts import tokens
from fleet.models import CommandLog

from .conftest import client_for

pytestmark = pytest.mark.django_db(transaction=True)

OBJREQUEST = "/control?command=objrequest&droneID=ACME_1&value=FlightStatus"


def with_token(user, scope: str = "operate"):  # type: ignore[no-untyped-def]
    client = client_for()
    key = tokens.issue(user, name="control", scope=scope).key
    client.defaults["HTTP_AUTHORIZATION"] = f"Token {key}"
    return client


def test_a_session_cookie_from_a_cross_site_link_sends_nothing(
    world_tx, ready_link, responding_drone
):
    response = client_for(world_tx.operator).get(
        OBJREQUEST, HTTP_REFERER="https://evil.example/page", HTTP_SEC_FETCH_SITE="cross-site"
    )
    assert response.status_code == 403 and response.json()["ok"] is False
    assert responding_drone.requests == [] and not CommandLog.objects.exists()


def test_a_read_only_token_sends_nothing(world_tx, ready_link, responding_drone):
    response = with_token(world_tx.operator, scope="read").get(OBJREQUEST)
    assert response.status_code == 403
    assert responding_drone.requests == [] and not CommandLog.objects.exists()


def test_an_operate_token_gets_the_drones_answer(world_tx, ready_link, responding_drone):
    response = with_token(world_tx.operator).get(OBJREQUEST)
    assert response.status_code == 200, response.content
    assert response.json()["ok"] is True
    assert [r["command"] for r in responding_drone.requests] == ["objrequest"]


def test_a_session_still_reads_by_get(world_tx):
    client = client_for(world_tx.operator)
    assert client.get("/control?command=discover").status_code == 200
    assert client.get("/control?command=getgear&droneID=ACME_1").status_code == 200

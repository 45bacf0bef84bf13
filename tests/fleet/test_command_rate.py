"""Commands and mission starts are rate-limited per user and per token (config/throttling.py):
a flood from one credential is answered 429 with Retry-After past the stated limit, and
nobody else is slowed. A flood is what one client sends in one second, up to 1 000
commands (the window is DRF's sliding one, in real time, as in production).
"""

from __future__ import annotations

import time
import uuid

import pytest
from django.conf import settings

from accounts import tokens
from config.throttling import parse_rate
from fleet.models import Drone, Role
from tests import factories

from .conftest import client_for

ARM = {"command": "arm", "params": {}}


def flood(client, most: int = 1000) -> list:  # type: ignore[no-untyped-def]
    """As many commands as the client gets answered within one second, up to `most`:
    each an unknown command, refused (400) before any database work, so that a 2-core
    machine sends more than the limit in the second.

    Only the answers that came back within one second of the first command's sending are
    kept: the throttle recorded each of them between its sending and its answer, so all
    lie in one window whatever the machine's load. A command sent just before the second
    ends but throttled after it may find the first one aged out, and tells nothing."""
    answers, started = [], time.time()  # DRF's throttle clock
    while len(answers) < most:
        answer = command(client, {"command": "warp"})
        if time.time() - started >= 1.0:
            return answers
        answers.append(answer)
    return answers


def full_flood(client, limit: int, tries: int = 5) -> list:  # type: ignore[no-untyped-def]
    """A flood with more commands in its second than the limit: a second in which this
    machine sent fewer tells nothing, so it is tried again once the throttle's window has
    emptied (a busy moment of a shared machine is not a fault of the throttle)."""
    for _ in range(tries):
        answers = flood(client)
        if len(answers) > limit:
            return answers
        time.sleep(1.1)  # the one-second window empties of the try's commands
    raise AssertionError(f"this machine sent at most {limit} commands in a second, {tries} times")


def token_client(user):  # type: ignore[no-untyped-def]
    client = client_for()
    client.defaults["HTTP_AUTHORIZATION"] = f"Token {tokens.issue(user, name='flood').key}"
    return client


def command(client, body: dict = ARM):  # type: ignore[no-untyped-def]
    return client.post("/api/v1/drones/ACME_1/commands/", body, content_type="application/json")


def test_a_thousand_commands_in_a_second_from_one_token_are_refused_past_the_limit(world_tx):
    limit, _ = parse_rate(settings.COMMAND_RATE)
    colleague = factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    # The process's first request loads the whole API; made by another user, it is not
    # part of the flood's second.
    command(token_client(colleague), {"command": "warp"})
    answers = full_flood(token_client(world_tx.operator), limit)
    statuses = [answer.status_code for answer in answers]
    assert statuses[:limit] == [400] * limit
    assert statuses[limit:] == [429] * (len(statuses) - limit)
    assert 0 < float(answers[-1]["Retry-After"]) <= 1

    # The drone is offline: a command is checked and refused (409) without a broker.
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    assert command(token_client(colleague)).status_code == 409  # checked, not throttled


@pytest.fixture
def slow_rates(settings):  # type: ignore[no-untyped-def]
    """Rates per minute, so what follows does not depend on this machine's speed."""
    settings.COMMAND_RATE = "5/min"
    settings.MISSION_START_RATE = "3/min"


def test_the_limit_is_per_user_across_their_tokens(world_tx, slow_rates):
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    user = factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    clients = [token_client(user) for _ in range(6)]
    assert [command(client).status_code for client in clients[:5]] == [409] * 5
    assert command(clients[5]).status_code == 429  # a fresh token: the same user
    assert command(client_for(user)).status_code == 429  # and their session


def test_the_control_endpoint_shares_the_limit(world_tx, slow_rates):
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    user = factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    client = token_client(user)
    for _ in range(5):
        command(client)
    answer = client.post("/control", {"command": "arm", "droneID": "ACME_1"})
    assert answer.status_code == 429 and answer.json()["ok"] is False
    assert "Retry-After" in answer


def test_mission_starts_are_limited_per_user(world_tx, slow_rates):
    user = factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    client = token_client(user)
    url = f"/api/v1/missions/{uuid.uuid4()}/start/"
    statuses = [client.post(url, {}, content_type="application/json").status_code for _ in range(5)]
    assert statuses == [404] * 3 + [429] * 2


def test_every_way_to_set_drones_moving_shares_its_limit(world_tx, slow_rates):
    """A panic call and a resume start drones like a mission start, and a panic release
    sends one home like a command: each counts against the same limit, so none is a way
    around it. Stopping and pausing, which only halt drones, are never limited."""
    Drone.objects.filter(drone_id="ACME_1").update(online=False)
    user = factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    client = token_client(user)
    mission = f"/api/v1/missions/{uuid.uuid4()}"
    starts = [f"{mission}/start/", "/api/v1/missions/panic/", f"{mission}/resume/"]
    assert all(_post(client, url).status_code != 429 for url in starts)  # 3/min
    assert [_post(client, url).status_code for url in starts] == [429] * 3
    for _ in range(5):  # 5/min
        command(client)
    assert _post(client, f"{mission}/release/").status_code == 429
    assert [_post(client, f"{mission}/{halt}/").status_code for halt in ("stop", "pause")] == [
        404,
        404,
    ]
    other = token_client(
        factories.person(world_tx.org, Role.OPERATOR, f"op-{uuid.uuid4().hex[:6]}")
    )
    assert _post(other, "/api/v1/missions/panic/").status_code != 429


def _post(client, url: str):  # type: ignore[no-untyped-def]
    return client.post(url, {}, content_type="application/json")

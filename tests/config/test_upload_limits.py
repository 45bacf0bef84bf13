"""Every address that takes a body refuses one over its stated limit with 413 and a clear
sentence, before any view runs, and stores nothing."""

from __future__ import annotations

import asyncio
import json

import pytest
from django.conf import settings
from django.test import Client

from config.bodylimits import BodyLimitASGI, limit_for
from config.bodylimits import human as limit_text

MiB = 1024 * 1024


@pytest.fixture
def admin(world) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(world.owner)
    return client


def _over(path: str) -> bytes:
    limit = limit_for(path)
    assert limit is not None
    return b"x" * (limit + 1)


def _assert_refused(response, limit: int) -> None:  # type: ignore[no-untyped-def]
    assert response.status_code == 413, response.content[:300]
    body = response.json()
    assert body["code"] == "too_large"
    assert "larger than" in body["error"] and "nothing was stored" in body["error"]
    assert limit_text(limit) in body["error"]


def test_each_address_states_its_limit():
    assert limit_for("/api/v1/missions/") == 16 * MiB
    assert limit_for("/api/v1/missions/import-plan/") == 16 * MiB
    assert limit_for("/api/v1/missions/logs/check/") == 51 * MiB
    assert limit_for("/api/v1/organisations/acme/envelope/") == 2 * MiB
    assert limit_for("/control") == 64 * 1024
    assert limit_for("/api/v1/drones/ACME_1/commands/") == 64 * 1024
    assert limit_for("/api/v1/token/") == settings.REQUEST_BODY_MAX_BYTES == MiB
    assert limit_for("/api/v1/logs/") is None  # streamed with LOG_UPLOAD_MAX_BYTES


def test_a_mission_over_the_limit_is_refused_and_not_created(admin, world):
    from missions.models import Mission

    response = admin.post(
        "/api/v1/missions/", _over("/api/v1/missions/"), content_type="application/json"
    )
    _assert_refused(response, 16 * MiB)
    assert not Mission.objects.exists()


def test_a_plan_file_over_the_limit_is_refused_and_not_imported(admin, world):
    from django.core.files.uploadedfile import SimpleUploadedFile

    from missions.models import Mission

    plan = SimpleUploadedFile("big.plan", _over("/api/v1/missions/import-plan/"))
    response = admin.post("/api/v1/missions/import-plan/", {"file": plan})
    _assert_refused(response, 16 * MiB)
    assert not Mission.objects.exists()


def test_a_mission_log_over_the_limit_is_refused(admin, world):
    from django.core.files.uploadedfile import SimpleUploadedFile

    log = SimpleUploadedFile("mission.json", _over("/api/v1/missions/logs/check/"))
    _assert_refused(admin.post("/api/v1/missions/logs/check/", {"file": log}), 51 * MiB)


def test_an_envelope_over_the_limit_is_refused_and_the_stored_one_stays(admin, world):
    path = f"/api/v1/organisations/{world.org.slug}/envelope/"
    before = admin.get(path).json()
    response = admin.put(path, _over(path), content_type="application/json")
    _assert_refused(response, 2 * MiB)
    assert admin.get(path).json() == before
    page = admin.post("/organisation/envelope/", {"envelope": "x" * (2 * MiB + 1)})
    assert page.status_code == 413
    assert admin.get(path).json() == before


def test_a_command_over_the_limit_is_refused_and_not_logged(admin, world):
    from fleet.models import CommandLog

    for path in ("/control", f"/api/v1/drones/{world.drone.drone_id}/commands/"):
        response = admin.post(path, _over(path), content_type="application/json")
        _assert_refused(response, 64 * 1024)
    assert not CommandLog.objects.exists()


def test_any_other_address_has_the_default_limit_and_a_body_under_it_reaches_the_view(world):
    client = Client()
    response = client.post(
        "/api/v1/token/", _over("/api/v1/token/"), content_type="application/json"
    )
    _assert_refused(response, MiB)
    small = client.post(
        "/api/v1/token/",
        json.dumps({"username": "owner", "password": "wrong"}),
        content_type="application/json",
    )
    assert small.status_code in (400, 401, 403)  # the view ran and refused the credentials
    assert small.json()["code"] != "too_large"


def test_a_form_with_too_many_fields_is_refused_with_413(world):
    fields = {f"f{i}": "1" for i in range(settings.DATA_UPLOAD_MAX_NUMBER_FIELDS + 1)}
    response = Client().post("/accounts/login/", fields)
    assert response.status_code == 413
    assert "more than 1000 fields" in response.json()["error"]


def _through_asgi(
    path: str, chunks: list[bytes], headers: list | None = None
) -> tuple[int, dict, bytes]:
    """One request without a Content-Length through BodyLimitASGI in front of an app
    that reads the whole body and stores it: (status, JSON body, what the app stored)."""
    stored = bytearray()

    async def app(scope, receive, send):  # type: ignore[no-untyped-def]
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            stored.extend(message.get("body", b""))
            if not message.get("more_body"):
                break
        await send({"type": "http.response.start", "status": 201, "headers": []})
        await send({"type": "http.response.body", "body": b"{}"})

    async def run() -> tuple[int, dict]:
        pending = [{"type": "http.request", "body": c, "more_body": i < len(chunks) - 1}
                   for i, c in enumerate(chunks)]  # fmt: skip
        sent: list[dict] = []

        async def receive() -> dict:
            return pending.pop(0) if pending else {"type": "http.disconnect"}

        async def send(message: dict) -> None:
            sent.append(message)

        scope = {"type": "http", "method": "PUT", "path": path, "headers": headers or []}
        await BodyLimitASGI(app)(scope, receive, send)
        body = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
        return sent[0]["status"], json.loads(body)

    status, body = asyncio.run(run())
    return status, body, bytes(stored)


def test_a_body_without_a_length_is_cut_off_at_the_limit_before_django_reads_it(world_tx):
    from accounts import tokens

    path = f"/api/v1/organisations/{world_tx.org.slug}/envelope/"
    key = tokens.issue(world_tx.owner, organisation=world_tx.org).key
    signed = [(b"authorization", f"Token {key}".encode())]
    status, body, _ = _through_asgi(path, [b"x" * MiB, b"x" * MiB, b"x" * MiB], signed)
    assert status == 413 and body["code"] == "too_large"
    status, _, stored = _through_asgi(path, [b"{}"], signed)
    assert status == 201 and stored == b"{}"


def test_a_body_larger_than_the_default_is_taken_only_from_a_signed_in_sender(world_tx):
    """Missions, plans and envelopes take more than REQUEST_BODY_MAX_BYTES: a stranger is
    answered before any of it is read."""
    for path in ("/api/v1/missions/", "/api/v1/missions/logs/check/", "/organisation/envelope/"):
        status, body, stored = _through_asgi(path, [b"x" * MiB] * 3)
        assert (status, body["code"], stored) == (401, "not_authenticated", b""), path
    bad = [(b"authorization", b"Token sky_wrong")]
    status, _, stored = _through_asgi("/api/v1/missions/", [b"{}"], bad)
    assert status == 401 and stored == b""
    status, _, stored = _through_asgi("/api/v1/token/", [b"{}"])  # the default limit: open
    assert status == 201 and stored == b"{}"


def test_an_anonymous_mission_body_is_refused_before_a_megabyte_is_read(live_asgi, world_tx):
    from tests.logs.test_upload_gate import MB, stream_upload

    headers = {"Content-Type": "application/json"}
    for chunked in (False, True):
        outcome = stream_upload(live_asgi.url, "/api/v1/missions/", headers, chunked=chunked)
        assert outcome.status in (401, 413) and outcome.taken < MB, outcome

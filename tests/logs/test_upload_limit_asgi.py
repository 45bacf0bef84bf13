"""The ASGI guard refuses oversized uploads before Django has read (or spooled) the body."""

from __future__ import annotations

import asyncio
import json
from concurrent.futures import ThreadPoolExecutor

import pytest

from logs.asgi import UploadLimitMiddleware

pytestmark = pytest.mark.usefixtures("logs_settings")


class RecordingApp:
    """Stands in for Django's ASGI app: reads the whole body, then answers 201."""

    def __init__(self) -> None:
        self.body = b""
        self.called = False
        self.disconnected = False

    async def __call__(self, scope, receive, send):  # type: ignore[no-untyped-def]
        self.called = True
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                self.disconnected = True
                return  # what Django's handler does on RequestAborted
            self.body += message.get("body", b"")
            if not message.get("more_body"):
                break
        await send({"type": "http.response.start", "status": 201, "headers": []})
        await send({"type": "http.response.body", "body": b"{}"})


def call(app, *, path: str, headers: list, chunks: list[bytes]):  # type: ignore[no-untyped-def]
    """Run one request through `app`; returns (status, body, chunks the client had to send)."""

    async def run():  # type: ignore[no-untyped-def]
        sent: list[dict] = []
        pending = [
            {"type": "http.request", "body": c, "more_body": i < len(chunks) - 1}
            for i, c in enumerate(chunks)
        ]
        delivered = 0

        async def receive():  # type: ignore[no-untyped-def]
            nonlocal delivered
            if pending:
                delivered += 1
                return pending.pop(0)
            return {"type": "http.disconnect"}

        async def send(message):  # type: ignore[no-untyped-def]
            sent.append(message)

        scope = {"type": "http", "method": "POST", "path": path, "headers": headers}
        await app(scope, receive, send)
        status = next(m["status"] for m in sent if m["type"] == "http.response.start")
        body = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
        return status, body, delivered

    with ThreadPoolExecutor(1) as pool:  # Playwright may hold a loop in this thread
        return pool.submit(asyncio.run, run()).result()


def test_an_announced_oversized_upload_is_refused_without_reading_a_byte(settings):
    settings.LOG_UPLOAD_MAX_BYTES = 1000
    inner = RecordingApp()
    status, body, delivered = call(
        UploadLimitMiddleware(inner),
        path="/api/v1/logs/",
        headers=[(b"content-length", str(10**9).encode())],
        chunks=[b"x" * 1000] * 3,
    )
    assert status == 413 and delivered == 0 and not inner.called
    assert json.loads(body) == {
        "error": "The file is larger than the upload limit of 1000 bytes.",
        "code": "too_large",
        "fields": {},
    }


def test_a_body_growing_past_the_limit_is_cut_off_and_answered_413(settings):
    settings.LOG_UPLOAD_MAX_BYTES = 1000
    inner = RecordingApp()
    chunk = b"x" * 32 * 1024
    status, _, delivered = call(
        UploadLimitMiddleware(inner), path="/api/v1/logs/", headers=[], chunks=[chunk] * 100
    )
    assert status == 413 and inner.disconnected
    assert delivered == 3  # 96 KB read of 3.2 MB: the limit plus the multipart slack
    assert len(inner.body) == 2 * len(chunk)


def test_uploads_within_the_limit_and_other_paths_pass_through(settings):
    settings.LOG_UPLOAD_MAX_BYTES = 1000
    status, _, _ = call(
        UploadLimitMiddleware(RecordingApp()),
        path="/api/v1/logs/",
        headers=[(b"content-length", b"900")],
        chunks=[b"x" * 900],
    )
    assert status == 201
    inner = RecordingApp()
    status, _, _ = call(
        UploadLimitMiddleware(inner), path="/api/v1/missions/", headers=[], chunks=[b"y" * 10**6]
    )
    assert status == 201 and len(inner.body) == 10**6


def test_the_served_application_refuses_an_announced_oversized_upload_at_once(live_asgi, world_tx):
    """Through uvicorn and config.asgi: an operator announcing too much gets 413 before any
    body byte is sent (a stranger gets 401 even earlier, tests/logs/test_upload_gate.py)."""
    import http.client
    from urllib.parse import urlsplit

    from django.conf import settings

    from accounts import tokens

    url = urlsplit(live_asgi.url)
    connection = http.client.HTTPConnection(url.hostname, url.port, timeout=10)
    connection.putrequest("POST", "/api/v1/logs/")
    connection.putheader("Content-Type", "multipart/form-data; boundary=x")
    connection.putheader("Content-Length", str(settings.LOG_UPLOAD_MAX_BYTES * 2))
    connection.putheader("Authorization", f"Token {tokens.issue(world_tx.operator).key}")
    connection.endheaders()
    response = connection.getresponse()
    assert response.status == 413
    connection.close()

"""An upload is let in only once its sender is known to be allowed to send it.

The attacker's side, against the real server (uvicorn and config.asgi) over a raw socket:
the client streams as fast as the server takes bytes, and what the server took is what the
client's kernel managed to hand over (sent minus what still waits in the client's queue),
so the kernel's buffers on both sides count against the server.
"""

from __future__ import annotations

import fcntl
import json
import select
import socket
import struct
import termios
import time
from dataclasses import dataclass
from urllib.parse import urlsplit

import pytest

MB = 1024 * 1024
ANNOUNCED = 1536 * MB  # 1.5 GB
LOG_PATH = "/api/v1/logs/"
TILE_PATH = "/admin/tiles/tileset/add/"
# Stop pushing once the server has taken nothing for this long: it is not reading.
STALL_S = 2.0


@dataclass
class Outcome:
    status: int | None
    body: dict
    taken: int


def _head(path: str, headers: dict[str, str], chunked: bool, announced: int = ANNOUNCED) -> bytes:
    lines = [f"POST {path} HTTP/1.1", "Host: 127.0.0.1"]
    lines += [f"{name}: {value}" for name, value in headers.items()]
    lines.append("Transfer-Encoding: chunked" if chunked else f"Content-Length: {announced}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def _unsent(sock: socket.socket) -> int:
    """Bytes still in this socket's send queue, not yet taken by the server's side."""
    try:
        return struct.unpack("i", fcntl.ioctl(sock, termios.TIOCOUTQ, b"\0\0\0\0"))[0]
    except OSError:
        return 0


def _status(data: bytes) -> tuple[int | None, dict]:
    if not data.startswith(b"HTTP/1.1 "):
        return None, {}
    head, _, body = data.partition(b"\r\n\r\n")
    try:
        return int(head.split()[1]), json.loads(body or b"{}")
    except ValueError:
        return int(head.split()[1]), {}


def stream_upload(
    server_url: str,
    path: str,
    headers: dict[str, str],
    *,
    chunked: bool,
    limit: int = ANNOUNCED,
    prefix: bytes = b"",
    announced: int = ANNOUNCED,
) -> Outcome:
    """POST `path` announcing 1.5 GB (or chunked), pushing body bytes (after `prefix`)
    until the server answers, stops reading or drops the connection."""
    url = urlsplit(server_url)
    sock = socket.create_connection((url.hostname, url.port), timeout=10)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 64 * 1024)
    sock.sendall(_head(path, headers, chunked, announced))
    if prefix:
        sock.sendall((b"%x\r\n" % len(prefix)) + prefix + b"\r\n" if chunked else prefix)
    block = b"x" * 64 * 1024
    frame = (b"%x\r\n" % len(block)) + block + b"\r\n" if chunked else block
    sent, answer, last_progress = 0, b"", time.monotonic()
    sock.setblocking(False)
    try:
        while sent < limit and time.monotonic() - last_progress < STALL_S:
            readable, writable, _ = select.select([sock], [sock], [], 0.2)
            if readable:
                answer += sock.recv(65536)
                break
            if writable:
                sent += sock.send(frame)
                last_progress = time.monotonic()
        taken = sent - _unsent(sock)
        answer += _read_answer(sock)
    except (BrokenPipeError, ConnectionResetError):
        taken = sent
    finally:
        sock.close()
    return Outcome(*_status(answer), taken=taken)


def _read_answer(sock: socket.socket) -> bytes:
    data = b""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and b"\r\n\r\n" not in data:
        if select.select([sock], [], [], 0.2)[0]:
            try:
                chunk = sock.recv(65536)
            except ConnectionResetError:
                break
            if not chunk:
                break
            data += chunk
    return data


def _token(user, scope: str = "operate", organisation=None) -> dict[str, str]:  # type: ignore[no-untyped-def]
    from accounts import tokens

    issued = tokens.issue(user, scope=scope, organisation=organisation)
    return {"Authorization": f"Token {issued.key}"}


def _session(user) -> dict[str, str]:  # type: ignore[no-untyped-def]
    from django.test import Client

    client = Client()
    client.force_login(user)
    return {"Cookie": f"sessionid={client.cookies['sessionid'].value}"}


MULTIPART = {"Content-Type": "multipart/form-data; boundary=x"}


@pytest.mark.parametrize("chunked", [False, True], ids=["content-length", "chunked"])
def test_an_anonymous_gigabyte_upload_is_refused_before_a_megabyte_is_read(
    live_asgi, world_tx, chunked
):
    outcome = stream_upload(live_asgi.url, LOG_PATH, MULTIPART, chunked=chunked)
    assert outcome.status == 401, outcome
    assert outcome.body["code"] == "not_authenticated"
    assert outcome.taken < MB, f"the server took {outcome.taken} bytes"


@pytest.mark.parametrize("chunked", [False, True], ids=["content-length", "chunked"])
def test_an_anonymous_tile_upload_to_the_admin_is_refused_before_a_megabyte_is_read(
    live_asgi, world_tx, chunked
):
    outcome = stream_upload(live_asgi.url, TILE_PATH, MULTIPART, chunked=chunked)
    assert outcome.status == 401, outcome
    assert outcome.taken < MB, f"the server took {outcome.taken} bytes"


def test_a_wrong_token_is_refused_before_the_body(live_asgi, world_tx):
    headers = {**MULTIPART, "Authorization": "Token sky_not-a-token"}
    outcome = stream_upload(live_asgi.url, LOG_PATH, headers, chunked=True)
    assert outcome.status == 401 and outcome.taken < MB, outcome


def test_a_read_only_token_is_refused_before_the_body(live_asgi, world_tx):
    headers = {**MULTIPART, **_token(world_tx.operator, scope="read")}
    outcome = stream_upload(live_asgi.url, LOG_PATH, headers, chunked=True)
    assert outcome.status == 403 and outcome.body["code"] == "read_only_token", outcome
    assert outcome.taken < MB


def test_a_viewer_is_refused_before_the_body(live_asgi, world_tx):
    headers = {**MULTIPART, **_token(world_tx.viewer)}
    outcome = stream_upload(live_asgi.url, LOG_PATH, headers, chunked=False)
    assert outcome.status == 403 and outcome.body["code"] == "permission_denied", outcome
    assert outcome.taken < MB


def test_a_token_of_an_organisation_where_its_user_is_a_viewer_is_refused(live_asgi, world_tx):
    from fleet.models import Membership, Role

    Membership.objects.create(user=world_tx.viewer, organisation=world_tx.other_org, role=Role.OPERATOR)  # fmt: skip
    headers = {**MULTIPART, **_token(world_tx.viewer, organisation=world_tx.org)}
    outcome = stream_upload(live_asgi.url, LOG_PATH, headers, chunked=True)
    assert outcome.status == 403 and outcome.taken < MB, outcome


def test_a_session_without_the_csrf_token_is_refused_before_the_body(live_asgi, world_tx):
    headers = {**MULTIPART, **_session(world_tx.operator)}
    outcome = stream_upload(live_asgi.url, LOG_PATH, headers, chunked=True)
    assert outcome.status == 403 and "CSRF" in outcome.body["error"], outcome
    assert outcome.taken < MB


def test_a_signed_in_member_without_the_admin_right_cannot_send_tiles(live_asgi, world_tx):
    headers = {**MULTIPART, **_session(world_tx.owner)}  # an organisation admin, not staff
    outcome = stream_upload(live_asgi.url, TILE_PATH, headers, chunked=True)
    assert outcome.status == 403 and outcome.taken < MB, outcome


def _post(url: str, headers: dict[str, str], body: bytes) -> tuple[int, dict]:
    import http.client

    parts = urlsplit(url)
    connection = http.client.HTTPConnection(parts.hostname, parts.port, timeout=30)
    connection.request("POST", LOG_PATH, body=body, headers=headers)
    response = connection.getresponse()
    status, payload = response.status, json.loads(response.read() or b"{}")
    connection.close()
    return status, payload


def _not_a_log() -> bytes:
    return (
        b'--x\r\nContent-Disposition: form-data; name="file"; filename="notes.txt"\r\n'
        b"Content-Type: application/octet-stream\r\n\r\nnot a flight log\r\n--x--\r\n"
    )


def test_an_operator_passes_the_gate_and_the_view_judges_the_file(live_asgi, world_tx):
    from logs.models import FlightLog

    status, body = _post(live_asgi.url, {**MULTIPART, **_token(world_tx.operator)}, _not_a_log())
    assert status == 400 and "not a flight log format" in body["error"], body
    assert not FlightLog.objects.exists()


def test_the_meter_sees_what_an_admitted_upload_sends(live_asgi, world_tx):
    """The same client against an operator's upload, which the server reads: it takes
    everything sent (here 8 MB of an announced 1.5 GB), so the figures above are real."""
    headers = {**MULTIPART, **_token(world_tx.operator)}
    part = b'--x\r\nContent-Disposition: form-data; name="file"; filename="big.ulg"\r\n\r\n'
    outcome = stream_upload(
        live_asgi.url, LOG_PATH, headers, chunked=False, limit=8 * MB, prefix=part
    )
    assert outcome.taken >= 8 * MB - 256 * 1024, outcome


def test_a_superuser_passes_the_tile_gate(live_asgi, world_tx):
    from django.contrib.auth import get_user_model

    root = get_user_model().objects.create_superuser("root", password="pw-for-tests-1")
    headers = {**MULTIPART, **_session(root)}
    part = b'--x\r\nContent-Disposition: form-data; name="file"; filename="a.zip"\r\n\r\n'
    outcome = stream_upload(
        live_asgi.url, TILE_PATH, headers, chunked=False, limit=4 * MB, prefix=part,
        announced=100 * MB,
    )  # fmt: skip
    assert outcome.taken >= 4 * MB - 256 * 1024, outcome


def _open_upload(url: str, headers: dict[str, str]) -> socket.socket:
    """An upload that sent its headers and a first piece of its body, then waits."""
    parts = urlsplit(url)
    sock = socket.create_connection((parts.hostname, parts.port), timeout=10)
    sock.sendall(_head(LOG_PATH, headers, chunked=False) + b"--x\r\n")
    return sock


def _slots_held(path: str, user_id: int) -> int:
    from django.core.cache import cache

    from config.uploadgate import slot_key

    keys = [slot_key(path, user_id, index) for index in range(2)]
    return sum(cache.get(key) is not None for key in keys)


def test_a_third_concurrent_upload_of_one_user_gets_429_and_another_user_is_unaffected(
    live_asgi, world_tx, settings
):
    from tests.support.ground import wait_for

    assert settings.UPLOAD_MAX_CONCURRENT == 2
    operator = {**MULTIPART, **_token(world_tx.operator)}
    held = [_open_upload(live_asgi.url, operator) for _ in range(2)]
    try:
        # Both are admitted (each holds a slot) and reading their bodies: a few ms here,
        # 10 s for a loaded machine.
        assert wait_for(lambda: _slots_held(LOG_PATH, world_tx.operator.pk) == 2, timeout=10)
        third = stream_upload(live_asgi.url, LOG_PATH, operator, chunked=True)
        assert third.status == 429 and third.body["code"] == "too_many_uploads", third
        assert third.taken < MB
        status, _ = _post(live_asgi.url, {**MULTIPART, **_token(world_tx.owner)}, _not_a_log())
        assert status == 400  # the owner's upload reached the view
    finally:
        for sock in held:
            sock.close()
    # A finished (here: abandoned) upload gives its slot back.
    wait_for(lambda: _post(live_asgi.url, operator, _not_a_log())[0] == 400, timeout=10)

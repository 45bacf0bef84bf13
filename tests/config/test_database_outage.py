"""A database or Redis restart costs no request: the first request after PostgreSQL ends
every connection answers as before (the pool replaces the dead one), and a request during
an outage answers 503 with Retry-After in the API's error shape, not 500.

A real web process (uvicorn, as `make run` starts it) on the tests' PostgreSQL. The
PostgreSQL server is shared, so it is never stopped: its restart is played by ending
every backend of this test's database (pg_terminate_backend, what a restart does to
them), and the outage by a process pointed at a port nothing listens on. Redis is one of
the test's own, restarted at will.
"""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from email.message import Message

import pytest
from django.db import connection

from runtime.processes import Supervised, free_port, python_env
from tests.support.outage import REDIS_SERVER
from workers.ground import web_argv

pytestmark = pytest.mark.django_db(transaction=True)

WRONG_LOGIN = {"username": "nobody", "password": "wrong"}
# The web process under test names its connections (libpq's PGAPPNAME), so that only they
# are ended: this worker's own connections, used by the tests after this one, stay.
APP_NAME = "skyhive-outage-test"


def _web(tmp_path, **env: str) -> Supervised:  # type: ignore[no-untyped-def]
    port = free_port()
    environment = python_env(
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=connection.settings_dict["NAME"],
        PGAPPNAME=APP_NAME,
        **env,
    )
    web = Supervised("web", web_argv(port), environment, tmp_path / "web.log", port=port)
    return web.start().wait_ready(60)


def _post(url: str, body: dict) -> tuple[int, Message, dict]:
    request = urllib.request.Request(
        url, json.dumps(body).encode(), {"Content-Type": "application/json"}
    )
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, response.headers, _json(response.read())
    except urllib.error.HTTPError as error:
        return error.code, error.headers, _json(error.read())


def _json(body: bytes) -> dict:
    try:
        return json.loads(body)
    except ValueError:
        return {"not_json": body[:200].decode(errors="replace")}  # Django's 500 page


def _end_every_backend_of_this_database() -> int:
    """What a restart does to the web process's connections: they are ended, and gone
    (pg_terminate_backend only signals them) before the next request."""
    with connection.cursor() as cursor:
        cursor.execute(
            "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity "
            "WHERE datname = current_database() AND application_name = %s",
            [APP_NAME],
        )
        ended = cursor.fetchone()[0]
        deadline = time.monotonic() + 10
        while _backends(cursor) and time.monotonic() < deadline:
            time.sleep(0.05)
    return ended


def _backends(cursor) -> int:  # type: ignore[no-untyped-def]
    cursor.execute(
        "SELECT count(*) FROM pg_stat_activity "
        "WHERE datname = current_database() AND application_name = %s",
        [APP_NAME],
    )
    return cursor.fetchone()[0]


def test_the_first_request_after_the_database_ended_its_connections_is_answered(tmp_path):
    web = _web(tmp_path, DB_POOL="true")
    try:
        url = f"{web.url}/api/v1/token/"
        assert _post(url, WRONG_LOGIN)[0] == 403  # refused; the pool now holds a connection
        assert _end_every_backend_of_this_database() >= 1
        status, _, body = _post(url, WRONG_LOGIN)
        assert status == 403, body
        assert body["code"] == "authentication_failed"
    finally:
        web.stop()


@pytest.mark.parametrize("service", ["database", "redis"])
def test_a_request_during_an_outage_answers_503_with_retry_after(tmp_path, service):
    closed = free_port()  # nothing listens here: the service is down
    if service == "database":
        env = {"DATABASE_URL": f"postgresql://skyhive:skyhive@127.0.0.1:{closed}/skyhive"}
    else:
        env = {"REDIS_URL": f"redis://127.0.0.1:{closed}/0"}
    web = _web(tmp_path, DB_POOL="false", **env)
    try:
        status, headers, body = _post(f"{web.url}/api/v1/token/", WRONG_LOGIN)
    finally:
        web.stop()
    assert status == 503, body
    assert int(headers["Retry-After"]) > 0
    assert body["code"] == "service_unavailable" and body["error"]


def test_the_first_request_after_a_redis_restart_is_answered(tmp_path):
    port = free_port()
    argv = [REDIS_SERVER, "--port", str(port), "--bind", "127.0.0.1", "--save", ""]
    redis = Supervised("redis", argv, log_path=tmp_path / "redis.log", port=port)
    redis.start().wait_ready(20)
    web = _web(tmp_path, DB_POOL="true", REDIS_URL=f"redis://127.0.0.1:{port}/0")
    try:
        url = f"{web.url}/api/v1/token/"
        assert _post(url, WRONG_LOGIN)[0] == 403  # the throttle's cache connection is open
        redis.restart(20)  # every client connection ends with it
        status, _, body = _post(url, WRONG_LOGIN)
        assert status == 403, body
    finally:
        web.stop()
        redis.stop()

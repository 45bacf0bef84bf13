"""The check a pooled connection passes before it is lent (config/postgresql/pool_check.py): a live
connection passes, one whose server end was closed fails at once, even when it was lent a
moment ago, and one the server has only spoken on (a notification) still passes."""

from __future__ import annotations

import time

import psycopg
import pytest
from django.db import connection

from config.postgresql.pool_check import check_pooled

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def own_connection():  # type: ignore[no-untyped-def]
    params = connection.get_connection_params()
    conn = psycopg.connect(**params, autocommit=True)
    yield conn
    conn.close()


def _backend_gone(pid: int) -> bool:
    with connection.cursor() as cursor:
        cursor.execute("SELECT count(*) FROM pg_stat_activity WHERE pid = %s", [pid])
        return cursor.fetchone()[0] == 0


def test_a_live_connection_passes_lent_or_not(own_connection):
    check_pooled(own_connection)  # never lent: the server is asked
    check_pooled(own_connection)  # lent just now, nothing on its socket
    assert own_connection.execute("SELECT 1").fetchone() == (1,)


def test_a_connection_the_server_ended_fails_even_lent_a_moment_ago(own_connection):
    check_pooled(own_connection)
    pid = own_connection.info.backend_pid
    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_terminate_backend(%s)", [pid])
    deadline = time.monotonic() + 10
    while not _backend_gone(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    with pytest.raises(psycopg.OperationalError):
        check_pooled(own_connection)


def test_a_connection_the_server_spoke_on_is_asked_and_passes(own_connection):
    check_pooled(own_connection)
    own_connection.execute("LISTEN pool_check_probe")
    with connection.cursor() as cursor:
        cursor.execute("NOTIFY pool_check_probe")
    time.sleep(0.2)  # the notification reaches the idle connection's socket
    check_pooled(own_connection)
    assert own_connection.execute("SELECT 1").fetchone() == (1,)

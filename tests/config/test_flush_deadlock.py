"""A transactional test's flush that loses a deadlock to a process still at work (a
module's ground outlives each test) is tried again, not left undone for the next test."""

import re
import threading

import psycopg
import pytest
from django.core.management import call_command
from django.core.management.color import no_style
from django.core.management.sql import sql_flush
from django.db import connection

from runtime.processes import wait_for
from tests import factories

pytestmark = pytest.mark.django_db(transaction=True)


def _flush_order() -> list[str]:
    (statement,) = sql_flush(no_style(), connection, reset_sequences=False)
    return re.findall(r'"([^"]+)"', statement)


def _waiting_on_a_lock(dsn: str) -> bool:
    with psycopg.connect(dsn, autocommit=True) as watcher:
        row = watcher.execute(
            "SELECT count(*) FROM pg_locks WHERE NOT granted AND database = "
            "(SELECT oid FROM pg_database WHERE datname = current_database())"
        ).fetchone()
    return bool(row and row[0])


def test_a_flush_that_loses_a_deadlock_is_tried_again_and_empties_the_database():
    factories.organisation("acme")
    order = _flush_order()
    first, last = order[0], order[-1]
    params = connection.get_connection_params()
    dsn = psycopg.conninfo.make_conninfo(
        **{k: v for k, v in params.items() if k in ("dbname", "user", "password", "host", "port")}
    )
    other = psycopg.connect(dsn)
    holding = threading.Event()
    outcome: list[str] = []

    def other_process() -> None:
        # Holds the flush's last table, then waits for its first: the lock order of a
        # task that read one table and goes on to another while the flush runs.
        other.execute(f'SELECT 1 FROM "{last}" LIMIT 1')
        holding.set()
        wait_for(lambda: _waiting_on_a_lock(dsn), 30, interval=0.05)
        try:
            other.execute(f'SELECT 1 FROM "{first}" LIMIT 1')
            other.commit()
            outcome.append("committed")
        except psycopg.errors.DeadlockDetected:
            other.rollback()
            outcome.append("lost the deadlock")

    thread = threading.Thread(target=other_process)
    thread.start()
    assert holding.wait(10)
    try:
        call_command("flush", verbosity=0, interactive=False, inhibit_post_migrate=True)
    finally:
        thread.join(30)
        other.close()
    assert outcome, "the other transaction never ended"
    from fleet.models import Organisation

    assert not Organisation.objects.exists()

"""A transactional test's teardown leaves the next test the database `migrate` made: every
row a test wrote gone, the content types and permissions kept, and a flush that loses a
deadlock to a process still at work (a module's ground outlives each test) tried again,
not left undone."""

import threading

import psycopg
import pytest
from django.contrib.auth.models import Permission
from django.contrib.contenttypes.models import ContentType
from django.db import connection

from fleet.models import Drone, Organisation
from runtime.processes import wait_for
from tests import factories
from tests.support.flush import KEPT_TABLES, empty_database, tried_again_after_a_deadlock

pytestmark = pytest.mark.django_db(transaction=True)


def _rows_per_table() -> dict[str, int]:
    tables = connection.introspection.django_table_names(only_existing=True, include_views=False)
    with connection.cursor() as cursor:
        return {
            table: cursor.execute(f'SELECT count(*) FROM "{table}"').fetchone()[0]
            for table in tables
        }


def _dsn() -> str:
    params = connection.get_connection_params()
    return psycopg.conninfo.make_conninfo(
        **{k: v for k, v in params.items() if k in ("dbname", "user", "password", "host", "port")}
    )


def _waiting_on_a_lock(dsn: str) -> bool:
    with psycopg.connect(dsn, autocommit=True) as watcher:
        row = watcher.execute(
            "SELECT count(*) FROM pg_locks WHERE NOT granted AND database = "
            "(SELECT oid FROM pg_database WHERE datname = current_database())"
        ).fetchone()
    return bool(row and row[0])


def test_every_row_a_test_wrote_goes_and_what_migrate_wrote_stays():
    permissions, content_types = Permission.objects.count(), ContentType.objects.count()
    assert permissions and content_types
    org = factories.organisation("acme")
    factories.drone(org, "d1")
    # A row that refers to a kept table: it goes, the permission it names stays.
    factories.person(org).user_permissions.add(Permission.objects.first())

    truncated = empty_database()

    assert {Organisation._meta.db_table, Drone._meta.db_table} <= set(truncated)
    assert not KEPT_TABLES & set(truncated)
    left = {t: n for t, n in _rows_per_table().items() if n and t not in KEPT_TABLES}
    assert left == {}
    assert (Permission.objects.count(), ContentType.objects.count()) == (
        permissions,
        content_types,
    )


def test_an_empty_database_is_left_as_it_is():
    empty_database()
    assert empty_database() == []


def test_a_flush_that_loses_a_deadlock_is_tried_again_and_empties_the_database():
    factories.organisation("acme")
    tables = sorted(
        set(connection.introspection.django_table_names(only_existing=True, include_views=False))
        - KEPT_TABLES
    )
    first, last = tables[0], tables[-1]
    dsn = _dsn()
    other = psycopg.connect(dsn)
    holding = threading.Event()
    outcome: list[str] = []

    def other_process() -> None:
        # Writes to the last table the flush locks, then goes on to write the first: the
        # lock order of a task still at work while the flush runs.
        other.execute(f'LOCK TABLE "{last}" IN ROW EXCLUSIVE MODE')
        holding.set()
        wait_for(lambda: _waiting_on_a_lock(dsn), 30, interval=0.05)
        try:
            other.execute(f'LOCK TABLE "{first}" IN ROW EXCLUSIVE MODE')
            other.commit()
            outcome.append("committed")
        except psycopg.errors.DeadlockDetected:
            other.rollback()
            outcome.append("lost the deadlock")

    thread = threading.Thread(target=other_process)
    thread.start()
    assert holding.wait(10)
    try:
        tried_again_after_a_deadlock(empty_database)
    finally:
        thread.join(30)
        other.close()
    # The flush waited first, so its deadlock check ran first and ended its own
    # transaction: the other committed, and the flush's second attempt emptied the table.
    assert outcome == ["committed"]
    assert not Organisation.objects.exists()

"""Emptying the test database after a transactional test, at the cost of what it wrote.

Django's own teardown truncates every table and then runs `post_migrate` again to write
back the content types and permissions it just removed: about 290 ms of CPU (the test
process's and PostgreSQL's) per test, most of it the re-created rows and a new file for
every table and index, which every other session on the database then reads again. Here
the rows `migrate` wrote stay, and only the tables that hold rows are emptied, all writes
held off while it looks: the next test starts from the same database either way.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import psycopg
from django.core.management.color import no_style
from django.db import connections, transaction

# What `post_migrate` writes: fixed by the installed models, never by a test.
KEPT_TABLES = frozenset({"django_content_type", "auth_permission"})

# From this many rows a table is truncated rather than deleted from. Measured here: a
# deleted row costs up to 0.3 ms (an organisation's, checked against every table that
# refers to it), a truncation 60-330 ms whatever its rows.
BULK_ROWS = 200

# A flush that loses a deadlock is tried again this many times.
FLUSH_ATTEMPTS = 5


def empty_database(alias: str = "default") -> list[str]:
    """Empty the tables that hold rows, but for KEPT_TABLES; returns those emptied.

    Every other table is locked against writes first (EXCLUSIVE still lets readers in),
    so no row can land in a table between the look that found it empty and the commit.
    A few rows are deleted (the foreign keys are checked at commit, by then all gone);
    a table of BULK_ROWS or more is truncated, whose cost does not grow with its rows.
    """
    connection = connections[alias]
    tables = sorted(
        set(connection.introspection.django_table_names(only_existing=True, include_views=False))
        - KEPT_TABLES
    )
    if not tables:
        return []
    quote = connection.ops.quote_name
    with transaction.atomic(using=alias), connection.cursor() as cursor:
        cursor.execute(f"LOCK TABLE {', '.join(map(quote, tables))} IN EXCLUSIVE MODE")
        rows = _rows_up_to(cursor, [quote(table) for table in tables], BULK_ROWS)
        written = {table: n for table, n in zip(tables, rows, strict=True) if n}
        bulky = [table for table, n in written.items() if n >= BULK_ROWS]
        cursor.execute("SET CONSTRAINTS ALL DEFERRED")
        for table in written.keys() - set(bulky):
            cursor.execute(f"DELETE FROM {quote(table)}")
        # CASCADE brings in the tables that refer to a truncated one.
        for statement in connection.ops.sql_flush(no_style(), bulky, allow_cascade=True):
            cursor.execute(statement)
    return sorted(written)


def _rows_up_to(cursor: Any, tables: list[str], cap: int) -> list[int]:
    """Each table's number of rows, counted no further than `cap`, in one statement."""
    counts = ", ".join(
        f"(SELECT count(*) FROM (SELECT 1 FROM {t} LIMIT {cap}) AS s)" for t in tables
    )
    cursor.execute(f"SELECT {counts}")
    return list(cursor.fetchone())


def tried_again_after_a_deadlock(flush: Callable[[], Any]) -> Any:
    """Ground processes that outlive a test (a module's Celery worker and gateway) may be
    in a transaction that holds one table and waits for another the flush holds:
    PostgreSQL then ends one side with a deadlock error. When that side is the flush, its
    transaction was rolled back whole, and it is tried again rather than leaving the next
    test a database that was never emptied."""
    for attempt in range(1, FLUSH_ATTEMPTS + 1):
        try:
            return flush()
        except Exception as exc:
            if attempt == FLUSH_ATTEMPTS or not deadlock(exc):
                raise
    return None


def deadlock(exc: BaseException | None) -> bool:
    while exc is not None:
        if isinstance(exc, psycopg.errors.DeadlockDetected):
            return True
        exc = exc.__cause__
    return False

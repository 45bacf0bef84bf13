"""The check a pooled PostgreSQL connection passes before it is lent.

psycopg_pool's own check sends an empty query: a round trip to the server for every
request, on the way of every command. Most of what it finds, this finds without one:
a connection the server has closed (a restart, a terminated backend, the server stopped)
has something to read on its socket, the server's last message or the end of the stream,
while a live, idle connection has nothing. Only a dead host says nothing; a connection
that has not been lent for `FRESH_S` still gets the round trip, and one lent within it
cannot have outlived a host's restart. Whatever this finds suspicious gets the round trip,
which fails for a dead connection, and the pool then lends another.
"""

from __future__ import annotations

import select
import time
import weakref

import psycopg
from psycopg_pool import ConnectionPool

# A connection lent this recently has been talking to a live server (seconds).
FRESH_S = 1.0

# When each connection of the process's pools was last lent (monotonic seconds).
_lent_at: weakref.WeakKeyDictionary[psycopg.Connection, float] = weakref.WeakKeyDictionary()


def check_pooled(conn: psycopg.Connection) -> None:
    """Return quietly for a connection fit to lend; raise for one the pool must replace."""
    now = time.monotonic()
    if now - _lent_at.get(conn, -FRESH_S) >= FRESH_S or not _quiet(conn):
        ConnectionPool.check_connection(conn)
    _lent_at[conn] = now


def _quiet(conn: psycopg.Connection) -> bool:
    """Nothing waits on the connection's socket: the server has neither spoken nor closed."""
    if conn.closed:
        return False
    poller = select.poll()
    poller.register(conn.pgconn.socket, select.POLLIN)
    return not poller.poll(0)

"""Reads on the event loop, for the few requests where a trip to a worker thread and the
ORM would cost more than the query (a command's token and drone, config/command_route.py).

One psycopg connection per web process, made with Django's own connection parameters
and adapters (the same database, credentials, TLS options and time zone), in autocommit:
only single SELECTs run on it. It belongs to the event loop that opened it; another loop
(tests run one each) gets a fresh one. Any database error closes it and reaches the
caller, which then serves the request the ordinary way.

Rows come back as Django model instances (`instances`), built from their columns with the
fields' own conversions, so code that takes them cannot tell them from the ORM's.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence
from typing import Any

import psycopg
from django.db import connections
from django.db.models import Model


class _LoopConnection:
    def __init__(self, loop: asyncio.AbstractEventLoop, connection: psycopg.AsyncConnection):
        self.loop = loop
        self.connection = connection
        self.lock = asyncio.Lock()


_current: _LoopConnection | None = None


def _params() -> dict[str, Any]:
    params = connections["default"].get_connection_params()
    params.pop("cursor_factory", None)  # Django's is synchronous
    return params


async def _connection() -> _LoopConnection:
    global _current
    loop = asyncio.get_running_loop()
    current = _current
    if current is not None and current.loop is loop and not current.connection.closed:
        return current
    if current is not None:
        _discard(current)
    connection = await psycopg.AsyncConnection.connect(autocommit=True, **_params())
    await connection.execute("SET TIME ZONE 'UTC'")  # as Django sets its own
    _current = _LoopConnection(loop, connection)
    return _current


def _discard(current: _LoopConnection) -> None:
    global _current
    if _current is current:
        _current = None
    # Closed without awaiting: its loop may be another one, or gone.
    current.connection.pgconn.finish()


async def fetch_one(sql: str, params: Sequence[Any]) -> tuple | None:
    """The first row of one SELECT, or None."""
    current = await _connection()
    try:
        async with current.lock:
            cursor = await current.connection.execute(sql, params)
            return await cursor.fetchone()
    except psycopg.Error:
        _discard(current)
        raise


def columns(model: type[Model], alias: str) -> str:
    """The model's concrete columns, in field order, for a SELECT list."""
    return ", ".join(f'{alias}."{field.column}"' for field in model._meta.concrete_fields)


def instance(model: type[Model], values: Sequence[Any]) -> Model:
    """A model instance from its concrete columns' raw values (`columns`' order)."""
    fields = model._meta.concrete_fields
    connection = connections["default"]
    converted = [
        field.from_db_value(value, None, connection)
        if value is not None and hasattr(field, "from_db_value")
        else value
        for field, value in zip(fields, values, strict=True)
    ]
    return model.from_db("default", [field.attname for field in fields], converted)


def close() -> None:
    """Close this process's connection (a new one opens on next use)."""
    if _current is not None:
        _discard(_current)

"""A query on every command's path, turned into SQL once per shape rather than per call.

Django builds a query's SQL anew each time it is evaluated. For the lookup of a command's
drone, which carries its rules' reads as subqueries of the one statement
(fleet/commands.py), building the SQL costs the request thread many times what PostgreSQL
takes to answer it (docs/performance.md). A `Compiled` query is built once from a
queryset made with stand-in values; each call sends the same SQL with the call's values in
the stand-ins' places and turns the row into model instances as Django's own iteration
does (the objects of `select_related`, the annotations, the fields' converters).

What a shape's SQL contains may come from settings (a default a subquery falls back to):
a settings change forgets every compiled query.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import psycopg
from django.core.signals import setting_changed
from django.db import connections
from django.db.models import Model, QuerySet
from django.db.models.query import get_related_populators


class Compiled:
    """The SQL of `queryset` (made with `stand_ins` where the calls' values go) and what
    Django needs to turn its first row into a model instance."""

    def __init__(
        self, queryset: QuerySet, stand_ins: dict[str, Any], optional: tuple[str, ...] = ()
    ) -> None:
        self.using = queryset.db
        compiler = queryset.query.get_compiler(using=self.using)
        self.sql, params = compiler.as_sql()
        self.params = tuple(params)
        # Where each stand-in is among the parameters; one named `optional` may be absent
        # (a subquery that does not use it), any other must be there.
        self.slots = {}
        for name, value in stand_ins.items():
            found = _positions(self.params, value)
            if not found and name not in optional:
                raise ValueError(f"the stand-in for {name} is not a parameter of the query")
            if found:
                self.slots[name] = found
        # After as_sql: the columns (select), the model and related models they fill
        # (klass_info) and the annotations' columns.
        self.compiler = compiler
        fields = compiler.klass_info["select_fields"]
        self.model_columns = slice(fields[0], fields[-1] + 1)
        self.init_list = [
            column[0].target.attname for column in compiler.select[self.model_columns]
        ]
        self.populators = get_related_populators(compiler.klass_info, compiler.select, self.using)

    def first(self, **values: Any) -> Model | None:
        """The first row with `values` in the stand-ins' places, as a model instance."""
        params = list(self.params)
        for name, positions in self.slots.items():
            for position in positions:
                params[position] = values[name]
        connection = connections[self.using]
        with _prepared_cursor(connection) as cursor:
            cursor.execute(self.sql, params)
            row = cursor.fetchone()
        if row is None:
            return None
        compiler = copy.copy(self.compiler)
        compiler.connection = connection  # the converters' connection: this thread's
        (row,) = compiler.results_iter([[row]])
        found = self.compiler.klass_info["model"].from_db(
            self.using, self.init_list, row[self.model_columns]
        )
        for populator in self.populators:
            populator.populate(row, found)
        for name, column in compiler.annotation_col_map.items():
            setattr(found, name, row[column])
        return found


def _prepared_cursor(connection: Any) -> Any:
    """A cursor of `connection` that runs each statement as a prepared one: PostgreSQL
    plans a statement of this shape once per connection rather than on every call (for the
    command's drone lookup, its subqueries made planning 0.8 of the 1.0 ms PostgreSQL
    spent on it, docs/performance.md). Django's own cursors send the values inside the
    SQL text, which cannot be prepared. The wrapper is Django's, so statements are logged
    and errors translated as for any other query. Other databases get Django's cursor."""
    if connection.vendor != "postgresql":
        return connection.cursor()
    connection.ensure_connection()
    with connection.wrap_database_errors:
        return connection._prepare_cursor(_PreparingCursor(connection.connection))


class _PreparingCursor(psycopg.Cursor):
    """psycopg's server-side binding cursor, preparing every statement it runs."""

    def execute(self, query: Any, params: Any = None, **kwargs: Any) -> Any:
        kwargs.setdefault("prepare", True)
        return super().execute(query, params, **kwargs)


def _positions(params: tuple, stand_in: Any) -> list[int]:
    """Where the stand-in is among the parameters (its own type and value: a stand-in is
    chosen to be like no other value of the query)."""
    return [i for i, p in enumerate(params) if type(p) is type(stand_in) and p == stand_in]


class Shapes:
    """Compiled queries by shape, each compiled on first use by `build(shape)`."""

    def __init__(self, build: Callable[[Any], Compiled]) -> None:
        self.build = build
        self.compiled: dict[Any, Compiled] = {}
        setting_changed.connect(self._forget, weak=False)

    def __getitem__(self, shape: Any) -> Compiled:
        found = self.compiled.get(shape)
        if found is None:
            found = self.compiled[shape] = self.build(shape)
        return found

    def _forget(self, **kwargs: Any) -> None:
        self.compiled.clear()

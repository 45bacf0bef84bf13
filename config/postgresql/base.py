"""The database backend `DATABASES` names: Django's PostgreSQL backend, whose connection
pool checks a connection before lending it with `pool_check.check_pooled` rather than
psycopg_pool's round trip (`CONN_HEALTH_CHECKS` chooses whether a pool checks at all)."""

from __future__ import annotations

from typing import Any

from django.db.backends.postgresql import base
from psycopg_pool import ConnectionPool

from .pool_check import check_pooled


class DatabaseWrapper(base.DatabaseWrapper):
    @property
    def pool(self) -> Any:
        pool = super().pool
        # Django hands the pool psycopg_pool's own check; the pool keeps it as `_check`.
        if pool is not None and pool._check is ConnectionPool.check_connection:
            pool._check = check_pooled
        return pool

"""The environment the settings read, parsed by django-environ, with safe development defaults.

A value starting with ``$`` names another variable (django-environ's proxy); write ``\\$`` for a
literal leading dollar. Lists are comma-separated, their items stripped of spaces; an empty
number is an error, not its default.
"""

from __future__ import annotations

import os
from pathlib import Path

import environ
from django.core.exceptions import ImproperlyConfigured

BASE_DIR = Path(__file__).resolve().parent.parent

env = environ.Env()
env.escape_proxy = True

POSTGRESQL = "django.db.backends.postgresql"
# Django's PostgreSQL backend with the pool's connection check of config/postgresql.
BACKEND = "config.postgresql"
# Each process's connection pool (DB_POOL): kept open, at most this many, and how long a
# request waits for one.
POOL = {"min_size": 1, "max_size": 16, "timeout": 10}


def read_data_env(path: Path) -> None:
    """Load the KEY=VALUE file scripts/services.sh writes; the real environment wins."""
    environ.Env.read_env(path, overwrite=False)


def data_env_values(path: Path) -> dict[str, str]:
    """The KEY=VALUE pairs of that file as written ({} when there is none)."""
    if not path.is_file():
        return {}
    pairs = (line.split("=", 1) for line in path.read_text().splitlines() if "=" in line)
    return {key.strip(): value.strip() for key, value in pairs if not key.startswith("#")}


SERVICE_PORTS = ("PG_PORT", "REDIS_PORT", "MQTT_PORT")


def pin_test_ports(path: Path) -> None:
    """Point the service script's test profile (TEST_PG_PORT, ...) at the ports the
    profile file at `path` names: a test that runs `services.sh start test` then finds
    these services where they are. Taken from the file, not the environment, which may
    carry `make run`'s own ports (the Makefile exports MQTT_PORT)."""
    values = data_env_values(path)
    for name in SERVICE_PORTS:
        if name in values:
            os.environ[f"TEST_{name}"] = values[name]


def database_from_url(url: str) -> dict:
    """postgresql://user:pass@host:port/name?sslmode=… → Django DATABASES entry."""
    config = env.db_url_config(url)
    if config.get("ENGINE") != POSTGRESQL:
        raise ImproperlyConfigured(
            f"DATABASE_URL must be postgresql://…, got {url.split(':')[0]!r}"
        )
    options = config.get("OPTIONS", {})
    if env.bool("DB_PREPARED_STATEMENTS", True):
        # Lets the statements that ask for it (fleet.compiled: the queries on every
        # command's path) be prepared once per connection; Django's own cursors send
        # their values inside the SQL and are never prepared. Off behind a pooler that
        # cannot keep a connection's prepared statements (PgBouncer in transaction mode
        # before 1.21).
        options = {"prepare_threshold": 5, **options}
    return {
        **config,
        "ENGINE": BACKEND,
        "NAME": config["NAME"] or "skyhive",
        "HOST": config["HOST"] or "127.0.0.1",
        "PORT": str(config["PORT"] or 5432),
        # Under ASGI every request would otherwise open a new connection (~20 ms under
        # load); a pool per process keeps them. Django requires CONN_MAX_AGE 0 with a pool.
        "OPTIONS": ({"pool": dict(POOL), **options} if env.bool("DB_POOL", True) else options),
        "CONN_MAX_AGE": 0,
        # A connection is checked before its first use in a request (or a task, or a
        # process's unit of work) and replaced if dead: with the pool, by the pool before
        # it lends one (config/postgresql/pool_check.py), so the first request after a
        # PostgreSQL restart does not meet a stale connection.
        "CONN_HEALTH_CHECKS": True,
    }

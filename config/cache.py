"""The cache's Redis connections, one pool per server for the whole process.

Django keeps a cache object per context (`caches` is an asgiref `Local`), and under ASGI
each request runs in a context of its own: every request built a cache object, a
connection pool and a new connection to Redis (a TCP connect and its handshake on the
request's way, for the throttles' first read), and left the connection for the garbage
collector. The cache's `pool_class` hands every cache object the one pool of its server,
whose connections are kept and reused; redis-py makes a forked process (a Celery pool
process) start a pool of its own.
"""

from __future__ import annotations

import threading
from typing import Any

import redis

_lock = threading.Lock()
_pools: dict[tuple, redis.ConnectionPool] = {}


class ProcessConnectionPool(redis.ConnectionPool):
    """`from_url` gives the same pool for the same server and options, process-wide."""

    @classmethod
    def from_url(cls, url: str, **options: Any) -> redis.ConnectionPool:
        key = (cls, url, tuple(sorted((name, repr(value)) for name, value in options.items())))
        with _lock:
            pool = _pools.get(key)
            if pool is None:
                pool = _pools[key] = super().from_url(url, **options)
            return pool

"""The cache's Redis connections are kept for the process, not made per request."""

from __future__ import annotations

import asyncio

from django.core.cache import caches


def pools_of_concurrent_requests(count: int) -> list:
    """The cache's connection pool as each of `count` concurrent tasks (each in a context
    of its own, as each ASGI request is) finds it."""

    async def pool_of_one() -> object:
        return caches["default"]._cache._get_connection_pool(write=True)

    async def all_of_them() -> list:
        return await asyncio.gather(*(asyncio.create_task(pool_of_one()) for _ in range(count)))

    return asyncio.run(all_of_them())


def test_requests_in_contexts_of_their_own_share_one_pool_of_kept_connections():
    pools = pools_of_concurrent_requests(3)
    assert len({id(pool) for pool in pools}) == 1


def test_the_shared_pool_serves_the_cache():
    cache = caches["default"]
    cache.set("cache-pool-probe", 7, 5)
    assert cache.get("cache-pool-probe") == 7
    cache.delete("cache-pool-probe")

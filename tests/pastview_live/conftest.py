from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _no_snapshots_from_earlier_tests(request):  # type: ignore[no-untyped-def]
    """The service stores each drone's last state, and pages mark the drones they watch, in
    the shared test Redis; a later test would see them."""
    if not request.config.pluginmanager.hasplugin("django"):
        yield
        return
    import redis
    from django.conf import settings

    from pastview.runner import WATCH_KEY, snapshot_key

    client = redis.Redis.from_url(settings.REDIS_URL)
    keys = [WATCH_KEY, *(snapshot_key(d) for d in ("ACME_1", "GLOBEX_1"))]
    client.delete(*keys)
    yield
    client.delete(*keys)
    client.close()

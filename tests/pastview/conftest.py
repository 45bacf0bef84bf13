"""Past-view fixtures: a camera frame, and a clean Redis for the live tests."""

from __future__ import annotations

import pytest

from onboard.synthetic_camera import render_view


@pytest.fixture(scope="session")
def jpeg() -> bytes:
    """A small real JPEG from the simulator's camera."""
    return render_view((0.0, 0.0, -3.0), (0.0, 0.0, 0.0, 1.0), width=48, height=36)


@pytest.fixture
def no_snapshots_from_earlier_tests(settings):  # type: ignore[no-untyped-def]
    """The service stores each drone's last state, and pages mark the drones they watch, in
    the shared test Redis; a later test would see them. The live tests use it."""
    import redis

    from pastview.runner import WATCH_KEY, snapshot_key

    client = redis.Redis.from_url(settings.REDIS_URL)
    keys = [WATCH_KEY, *(snapshot_key(d) for d in ("ACME_1", "GLOBEX_1"))]
    client.delete(*keys)
    yield
    client.delete(*keys)
    client.close()

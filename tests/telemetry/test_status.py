"""Ingest counters reach the status API, the status page and /health."""

from __future__ import annotations

import pytest
from django.contrib.auth.models import User
from django.test import Client
from rest_framework.test import APIClient

from telemetry.ingest import Rejected
from workers.counters import KEY_PREFIX, Counters, _client


@pytest.fixture
def counters():
    _client().delete(KEY_PREFIX + "ingest")
    counters = Counters("ingest")
    yield counters
    _client().delete(KEY_PREFIX + "ingest")


def test_ingest_counters_show_on_the_status_api_page_and_health(world, counters):
    counters.incr("received", 12)
    counters.incr("stored", 30)
    counters.incr(f"dropped.{Rejected('not_json', '').reason}", 2)
    counters.incr("overflow", 1)
    counters.gauge("lag_s", 0.25)
    counters.flush()

    api = APIClient()
    api.force_authenticate(world.viewer)
    status = api.get("/api/v1/telemetry/status/").json()
    assert status["received_messages"] == 12 and status["stored_objects"] == 30
    assert status["dropped_messages"] == {"not_json": 2} and status["dropped_total"] == 2
    assert status["overflow_messages"] == 1 and status["lag_s"] == 0.25

    client = Client()
    client.force_login(world.viewer)
    page = client.get("/telemetry/status/").content.decode()
    assert "not_json" in page and "Overflow" in page
    client.force_login(User.objects.create_user("operations", is_staff=True))
    health = client.get("/health").json()  # the counters are for staff only
    assert health["processes"]["ingest"]["stored"] == 30

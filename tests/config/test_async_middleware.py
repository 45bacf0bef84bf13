"""Every middleware runs in the event loop under ASGI: a synchronous one would send each
request (a command's round trip included) to a worker thread and back."""

import pytest
from django.conf import settings
from django.test import AsyncClient
from django.utils.module_loading import import_string


def test_every_middleware_is_async_capable():
    sync_only = [
        path
        for path in settings.MIDDLEWARE
        if not getattr(import_string(path), "async_capable", False)
    ]
    assert sync_only == []


@pytest.mark.asyncio
async def test_static_files_are_served_from_the_event_loop():
    response = await AsyncClient().get("/static/js/alerts.js")
    assert response.status_code == 200
    assert int(response["Content-Length"]) > 0
    assert "javascript" in response["Content-Type"]


@pytest.mark.asyncio
async def test_a_missing_static_file_falls_through_to_django():
    response = await AsyncClient().get("/static/js/no-such-file.js")
    assert response.status_code == 404


@pytest.mark.django_db(transaction=True)
@pytest.mark.asyncio
async def test_other_paths_reach_the_views():
    response = await AsyncClient().get("/api/v1/drones/")
    assert response.status_code in (401, 403)

"""The progress websocket of a log: members follow processing, outsiders are refused.

Each test runs its coroutine on a fresh event loop in its own thread: Playwright's sync
API (the browser tests' session fixture) keeps a loop running in the main thread.
"""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

import pytest
from channels.db import database_sync_to_async
from channels.testing import WebsocketCommunicator

from logs.synth import synthetic_dataflash
from tests.support.websocket import connect_websocket

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.usefixtures("logs_settings")]


async def _connect(user, log_id: str) -> tuple[WebsocketCommunicator, bool, int | None]:  # type: ignore[no-untyped-def]
    return await connect_websocket(f"/ws/logs/{log_id}/", user)


def _uploaded_log(world, tmp_path):  # type: ignore[no-untyped-def]
    from logs.models import FlightLog

    source = tmp_path / "flight.bin"
    synthetic_dataflash(source, seconds=30)
    log = FlightLog.objects.create(
        organisation=world.org, owner=world.operator, name="flight.bin", size=1
    )
    log.upload_path.parent.mkdir(parents=True)
    source.rename(log.upload_path)
    return log


def in_own_loop(coroutine_function, *args):  # type: ignore[no-untyped-def]
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coroutine_function(*args)).result()


def test_members_see_progress_then_ready_while_a_log_is_processed(world_tx, tmp_path, monkeypatch):
    from logs import services

    monkeypatch.setattr(services, "PROGRESS_INTERVAL_S", 0.0)
    in_own_loop(_follow_processing, world_tx, tmp_path)


def test_outsiders_and_anonymous_visitors_cannot_follow_a_log(world_tx, tmp_path):
    in_own_loop(_refused, world_tx, tmp_path)


async def _follow_processing(world_tx, tmp_path):  # type: ignore[no-untyped-def]
    from logs import services

    log = await database_sync_to_async(_uploaded_log)(world_tx, tmp_path)
    communicator, connected, _ = await _connect(world_tx.viewer, str(log.pk))
    assert connected
    try:
        snapshot = await communicator.receive_json_from(timeout=5)
        assert snapshot == {"type": "status", "status": "processing", "progress": 0.0, "error": ""}
        assert await database_sync_to_async(services.process_log)(str(log.pk)) == "ready"
        events = []
        while not events or events[-1].get("status") == "processing":
            events.append(await communicator.receive_json_from(timeout=5))
        progress = [e["progress"] for e in events if e["type"] == "progress"]
        assert len(progress) >= 3 and progress == sorted(progress) and progress[-1] <= 0.95
        assert events[-1] == {"type": "status", "status": "ready", "progress": 1.0}
    finally:
        await communicator.disconnect()


async def _refused(world_tx, tmp_path):  # type: ignore[no-untyped-def]
    log = await database_sync_to_async(_uploaded_log)(world_tx, tmp_path)
    communicator, connected, code = await _connect(world_tx.outsider, str(log.pk))
    assert not connected and code == 4404
    await communicator.disconnect()

    from config.asgi import application

    anonymous = WebsocketCommunicator(
        application, f"/ws/logs/{log.pk}/", headers=[(b"origin", b"http://127.0.0.1")]
    )
    connected, code = await anonymous.connect()
    assert not connected and code == 4401
    await anonymous.disconnect()

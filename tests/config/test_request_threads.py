"""A request's synchronous work runs on a thread kept from an earlier request, one request
per thread at a time, never behind another request's unfinished work."""

import asyncio
import threading

import pytest
from asgiref.sync import sync_to_async
from channels.testing import HttpCommunicator
from django.http import HttpResponse
from django.urls import path

from config.middleware import EventLoopASGIHandler
from config.request_threads import RequestThreads

pytestmark = pytest.mark.asyncio


def _ident() -> int:
    return threading.get_ident()


async def test_one_request_after_another_uses_the_same_thread():
    threads = RequestThreads()
    async with threads.context():
        first = await sync_to_async(_ident)()
        assert await sync_to_async(_ident)() == first
    async with threads.context():
        assert await sync_to_async(_ident)() == first
    assert threads.idle_count == 1


async def test_concurrent_requests_have_threads_of_their_own():
    threads = RequestThreads()
    both_inside = asyncio.Barrier(2)

    async def request() -> int:
        async with threads.context():
            await both_inside.wait()
            return await sync_to_async(_ident)()

    first, second = await asyncio.gather(request(), request())
    assert first != second
    assert threads.idle_count == 2


async def test_a_thread_with_work_still_queued_is_retired_not_lent():
    threads = RequestThreads()
    release = threading.Event()
    async with threads.context() as busy:
        busy_ident = await sync_to_async(_ident)()
        # What a cancelled request leaves behind: a call still running on its thread.
        busy.submit(release.wait, 10)
    assert threads.idle_count == 0
    async with threads.context() as next_thread:
        assert next_thread is not busy
        assert await sync_to_async(_ident)() != busy_ident
    release.set()


async def test_idle_threads_beyond_the_limit_are_retired():
    threads = RequestThreads(keep_idle=1)
    barrier = asyncio.Barrier(3)

    async def request() -> None:
        async with threads.context():
            await barrier.wait()
            await sync_to_async(_ident)()

    await asyncio.gather(request(), request(), request())
    assert threads.idle_count == 1


def _where(request):  # type: ignore[no-untyped-def]
    return HttpResponse(str(threading.get_ident()))


urlpatterns = [path("where/", _where)]


@pytest.mark.urls(__name__)
async def test_the_asgi_handler_runs_sync_views_on_a_kept_thread():
    handler = EventLoopASGIHandler()
    seen = set()
    for _ in range(3):
        communicator = HttpCommunicator(
            handler, "GET", "/where/", headers=[(b"host", b"testserver")]
        )
        response = await communicator.get_response(timeout=10)
        assert response["status"] == 200
        seen.add(response["body"])
    assert len(seen) == 1
    assert int(seen.pop()) != threading.get_ident()


@pytest.mark.urls(__name__)
async def test_djangos_request_started_receivers_run_in_the_views_thread_without_a_trip_of_their_own(
    monkeypatch,
):
    """The connection receivers run once, in the thread the sync view then runs in, and
    the request makes no other trip to a thread before its view."""
    from django.core import signals

    import config.middleware as middleware

    ran = []
    monkeypatch.setattr(
        middleware, "THREAD_RECEIVERS", (lambda: ran.append(threading.get_ident()),)
    )
    handler = EventLoopASGIHandler()
    assert not any(
        receiver in signals.request_started._live_receivers(None)[0]
        for receiver in middleware.THREAD_RECEIVERS
    )
    communicator = HttpCommunicator(handler, "GET", "/where/", headers=[(b"host", b"testserver")])
    response = await communicator.get_response(timeout=10)
    assert response["status"] == 200
    assert ran == [int(response["body"])]


async def test_a_thread_given_back_forgets_what_was_to_run_before_its_first_call():
    threads = RequestThreads()
    ran = []
    async with threads.context(before_first_call=lambda: ran.append("started")):
        pass  # no synchronous call: nothing runs
    async with threads.context():
        await sync_to_async(_ident)()
    assert ran == []

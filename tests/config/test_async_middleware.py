"""Every middleware runs in the event loop under ASGI: a synchronous one would send each
request (a command's round trip included) to a worker thread and back."""

import threading
from http.cookies import SimpleCookie

import pytest
from asgiref.sync import sync_to_async
from channels.testing import HttpCommunicator
from django.conf import settings
from django.contrib.auth import get_user_model
from django.test import AsyncClient
from django.utils.module_loading import import_string

from config.middleware import EVENT_LOOP_VARIANTS, EventLoopASGIHandler


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


def _spy_on_hooks(monkeypatch) -> list[tuple[str, int]]:  # type: ignore[no-untyped-def]
    """Record the thread each middleware hook runs in."""
    seen: list[tuple[str, int]] = []
    for path in EVENT_LOOP_VARIANTS.values():
        cls = import_string(path)
        for hook in ("process_request", "process_view", "process_response"):
            original = getattr(cls, hook, None)
            if original is None:
                continue

            def spy(self, *args, _original=original, _name=f"{cls.__name__}.{hook}"):  # type: ignore[no-untyped-def]
                seen.append((_name, threading.get_ident()))
                return _original(self, *args)

            monkeypatch.setattr(cls, hook, spy)
    return seen


async def _asgi(method: str, path: str, body: bytes = b"", headers=()):  # type: ignore[no-untyped-def]
    """One request through the ASGI entry point's handler, in this event loop."""
    communicator = HttpCommunicator(
        EventLoopASGIHandler(),
        method,
        path,
        body=body,
        headers=[(b"host", b"testserver"), *headers],
    )
    response = await communicator.get_response(timeout=10)
    return response["status"], dict(response["headers"]), response["headers"], response["body"]


def test_the_settings_name_djangos_own_middleware_for_the_deploy_checks():
    assert "django.middleware.security.SecurityMiddleware" in settings.MIDDLEWARE
    assert "django.middleware.csrf.CsrfViewMiddleware" in settings.MIDDLEWARE
    assert set(EVENT_LOOP_VARIANTS) <= set(settings.MIDDLEWARE)


@pytest.mark.django_db(transaction=True)
@pytest.mark.asyncio
async def test_an_api_request_runs_every_middleware_hook_in_the_event_loop(monkeypatch):
    seen = _spy_on_hooks(monkeypatch)
    status, _, _, _ = await _asgi(
        "GET", "/api/v1/drones/", headers=[(b"authorization", b"Token x")]
    )
    assert status == 401
    names = {name for name, _ in seen}
    assert {"SessionMiddleware.process_request", "CsrfViewMiddleware.process_view"} <= names
    assert {
        "SecurityMiddleware.process_response",
        "XFrameOptionsMiddleware.process_response",
    } <= names
    assert {ident for _, ident in seen} == {threading.get_ident()}


def _cookies(raw_headers) -> dict[str, str]:  # type: ignore[no-untyped-def]
    jar = SimpleCookie()
    for name, value in raw_headers:
        if name.lower() == b"set-cookie":
            jar.load(value.decode())
    return {key: morsel.value for key, morsel in jar.items()}


@pytest.mark.django_db(transaction=True)
@pytest.mark.asyncio
async def test_a_form_post_is_still_checked_for_its_csrf_token_and_a_session_still_saved():
    form = [(b"content-type", b"application/x-www-form-urlencoded")]
    status, *_ = await _asgi("POST", "/accounts/login/", b"username=x&password=y", form)
    assert status == 403  # no CSRF token: refused before the view
    await sync_to_async(get_user_model().objects.create_user)("pilot", password="pw-123456")
    _, _, raw, _ = await _asgi("GET", "/accounts/login/")
    token = _cookies(raw)["csrftoken"]
    body = f"username=pilot&password=pw-123456&csrfmiddlewaretoken={token}".encode()
    cookie = [(b"cookie", f"csrftoken={token}".encode())]
    status, _, raw, _ = await _asgi("POST", "/accounts/login/", body, form + cookie)
    assert status == 302
    session = _cookies(raw)[settings.SESSION_COOKIE_NAME]  # saved, from a thread
    status, _, _, content = await _asgi(
        "GET",
        "/api/v1/me/",
        headers=[(b"cookie", f"{settings.SESSION_COOKIE_NAME}={session}".encode())],
    )
    assert status == 200 and b'"pilot"' in content

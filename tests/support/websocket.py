"""Open a websocket to the real ASGI app as a logged-in user (channels' communicator)."""

from __future__ import annotations

from asgiref.sync import sync_to_async
from channels.testing import WebsocketCommunicator


def session_cookie(user) -> bytes:  # type: ignore[no-untyped-def]
    """A saved login session for user, as the Cookie header value a browser would send."""
    from django.contrib.auth import BACKEND_SESSION_KEY, HASH_SESSION_KEY, SESSION_KEY
    from django.contrib.sessions.backends.db import SessionStore

    session = SessionStore()
    session[SESSION_KEY] = str(user.pk)
    session[BACKEND_SESSION_KEY] = "django.contrib.auth.backends.ModelBackend"
    session[HASH_SESSION_KEY] = user.get_session_auth_hash()
    session.save()
    return f"sessionid={session.session_key}".encode()


async def connect_websocket(
    path: str,
    user=None,
    timeout: float = 5,  # type: ignore[no-untyped-def]
) -> tuple[WebsocketCommunicator, bool, int | None]:
    """(communicator, connected, close code); anonymous when user is None."""
    from config.asgi import application

    headers = [(b"origin", b"http://127.0.0.1")]
    if user is not None:
        headers.append((b"cookie", await sync_to_async(session_cookie)(user)))
    communicator = WebsocketCommunicator(application, path, headers=headers)
    connected, code = await communicator.connect(timeout=timeout)
    return communicator, connected, code

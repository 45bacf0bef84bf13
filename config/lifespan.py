"""Reports each ASGI web process as a `web` instance on the operations page.

uvicorn sends the ASGI lifespan events that Channels' router does not take: this wrapper
answers them, starting a heartbeat (workers.counters) at startup and retiring it at
shutdown, and counts the HTTP requests and websocket connections the process serves.
Servers without lifespan events (daphne, the test client) pass straight through.
"""

from __future__ import annotations

from typing import Any

from workers.counters import Heartbeat, start_heartbeat

Scope = dict[str, Any]


class InstanceLifespan:
    def __init__(self, app: Any, process: str = "web") -> None:
        self.app = app
        self.process = process
        self.heartbeat: Heartbeat | None = None

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        kind = scope["type"]
        if kind == "lifespan":
            await self._lifespan(receive, send)
            return
        if self.heartbeat is not None:
            self.heartbeat.counters.incr("requests" if kind == "http" else "websockets")
        await self.app(scope, receive, send)

    async def _lifespan(self, receive: Any, send: Any) -> None:
        while True:
            message = await receive()
            if message["type"] == "lifespan.startup":
                try:
                    self.heartbeat = start_heartbeat(self.process)
                except Exception as exc:  # noqa: BLE001 - no report must not mean no web
                    await send({"type": "lifespan.startup.failed", "message": str(exc)})
                    return
                await send({"type": "lifespan.startup.complete"})
            elif message["type"] == "lifespan.shutdown":
                if self.heartbeat is not None:
                    self.heartbeat.stop()
                    self.heartbeat = None
                await send({"type": "lifespan.shutdown.complete"})
                return

"""`/ws/telemetry/<drone_id>/`: a drone's latest values, pushed by the ingest process.

Members of the drone's organisation only; server → client only. The consumer marks the
drone as watched so the ingest process pushes for it at all (see telemetry.live).
"""

from __future__ import annotations

import time

from channels.db import database_sync_to_async
from channels.generic.websocket import AsyncJsonWebsocketConsumer

from fleet.models import Drone

from . import live, queries


@database_sync_to_async
def _visible_drone(user, drone_id: str) -> Drone | None:  # type: ignore[no-untyped-def]
    return Drone.objects.for_user(user).filter(drone_id=drone_id).first()


@database_sync_to_async
def _latest(drone_pk: int) -> dict:
    return queries.latest(drone_pk)


@database_sync_to_async
def _mark_watched(drone_pk: int) -> None:
    live.mark_watched(drone_pk)


class TelemetryConsumer(AsyncJsonWebsocketConsumer):
    group: str | None = None
    drone_pk: int | None = None
    _marked_at = 0.0

    async def connect(self) -> None:
        user = self.scope.get("user")
        if user is None or not user.is_authenticated:
            await self.close(code=4401)
            return
        drone_id = self.scope["url_route"]["kwargs"]["drone_id"]
        drone = await _visible_drone(user, drone_id)
        if drone is None:
            # Same answer for "not yours" and "does not exist": no probing other fleets.
            await self.close(code=4403)
            return
        self.drone_pk = drone.pk
        self.group = live.group_name(drone.pk)
        await self.channel_layer.group_add(self.group, self.channel_name)
        await self.accept()
        await self._keep_watched()
        await self.send_json(
            {"type": "snapshot", "drone_id": drone_id, "objects": await _latest(drone.pk)}
        )

    async def _keep_watched(self) -> None:
        if time.monotonic() - self._marked_at >= live.WATCH_TTL_S / 3:
            self._marked_at = time.monotonic()
            await _mark_watched(self.drone_pk)

    async def disconnect(self, code: int) -> None:
        if self.group:
            await self.channel_layer.group_discard(self.group, self.channel_name)

    async def receive_json(self, content: dict, **kwargs: object) -> None:
        # Pages ping every 20 s so a drone silent for a while is still pushed when it resumes.
        await self._keep_watched()

    async def telemetry_update(self, event: dict) -> None:
        await self._keep_watched()
        await self.send_json({"type": "update", "objects": event["objects"]})

"""`/ws/telemetry/<drone_id>/`: a drone's latest values, pushed by the ingest process.

Members of the drone's organisation only; server → client only. The consumer marks the
drone as watched so the ingest process pushes for it at all (see telemetry.live).
"""

from __future__ import annotations

import time
from typing import Any

from channels.db import database_sync_to_async

from fleet.consumers import GroupConsumer
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


class TelemetryConsumer(GroupConsumer):
    drone_pk: int | None = None
    _marked_at = 0.0

    async def authorise(self, user: Any) -> Drone | None:
        # Same answer for "not yours" and "does not exist": no probing other fleets.
        return await _visible_drone(user, self.scope["url_route"]["kwargs"]["drone_id"])

    def group_for(self, drone: Drone) -> str:
        return live.group_name(drone.pk)

    async def joined(self, drone: Drone) -> None:
        self.drone_pk = drone.pk

    async def welcome(self, drone: Drone) -> None:
        await self._keep_watched()
        await self.send_json(
            {"type": "snapshot", "drone_id": drone.drone_id, "objects": await _latest(drone.pk)}
        )

    async def _keep_watched(self) -> None:
        if time.monotonic() - self._marked_at >= live.WATCH_TTL_S / 3:
            self._marked_at = time.monotonic()
            await _mark_watched(self.drone_pk)

    async def receive_json(self, content: Any, **kwargs: object) -> None:
        # Pages ping every 20 s so a drone silent for a while is still pushed when it resumes.
        await self._keep_watched()

    async def telemetry_update(self, event: dict) -> None:
        await self._keep_watched()
        await self.send_json({"type": "update", "objects": event["objects"]})

"""Processing progress of one flight log, pushed to its page: server → client only."""

from __future__ import annotations

from channels.db import database_sync_to_async
from channels.generic.websocket import AsyncJsonWebsocketConsumer

from logs.models import FlightLog


@database_sync_to_async
def _visible_log(user, log_id: str) -> FlightLog | None:  # type: ignore[no-untyped-def]
    return FlightLog.objects.for_user(user).filter(pk=log_id).first()


@database_sync_to_async
def _snapshot(log_id: str) -> dict:
    log = FlightLog.objects.filter(pk=log_id).first()
    if log is None:
        return {"type": "status", "status": "deleted", "progress": 0, "error": ""}
    return {"type": "status", "status": log.status, "progress": log.progress, "error": log.error}


class LogProgressConsumer(AsyncJsonWebsocketConsumer):
    """`/ws/logs/<uuid>/`: the log's status now, then every progress and status change."""

    group: str | None = None

    async def connect(self) -> None:
        user = self.scope.get("user")
        if user is None or not user.is_authenticated:
            await self.close(code=4401)
            return
        log = await _visible_log(user, str(self.scope["url_route"]["kwargs"]["log_id"]))
        if log is None:
            # Outsiders learn nothing, not even that the log exists.
            await self.close(code=4404)
            return
        self.group = log.group_name
        await self.channel_layer.group_add(self.group, self.channel_name)
        await self.accept()
        # Read after joining the group, so no change between the two is lost.
        await self.send_json(await _snapshot(str(log.pk)))

    async def disconnect(self, code: int) -> None:
        if self.group:
            await self.channel_layer.group_discard(self.group, self.channel_name)

    async def receive_json(self, content: dict, **kwargs: object) -> None:
        return  # clients only listen

    async def flightlog_event(self, event: dict) -> None:
        await self.send_json(event["payload"])

"""`/ws/missions/<id>/`: a mission's live progress, for members of its organisation only."""

from __future__ import annotations

from channels.db import database_sync_to_async
from channels.generic.websocket import AsyncJsonWebsocketConsumer

from missions.live import group_name
from missions.models import Mission


@database_sync_to_async
def _visible(user, mission_id: str) -> bool:  # type: ignore[no-untyped-def]
    return Mission.objects.for_user(user).filter(pk=mission_id).exists()


class MissionConsumer(AsyncJsonWebsocketConsumer):
    group: str | None = None

    async def connect(self) -> None:
        user = self.scope.get("user")
        if user is None or not user.is_authenticated:
            await self.close(code=4401)
            return
        mission_id = str(self.scope["url_route"]["kwargs"]["mission_id"])
        if not await _visible(user, mission_id):
            await self.close(code=4403)
            return
        self.group = group_name(mission_id)
        await self.channel_layer.group_add(self.group, self.channel_name)
        await self.accept()

    async def disconnect(self, code: int) -> None:
        if self.group:
            await self.channel_layer.group_discard(self.group, self.channel_name)

    async def receive_json(self, content: dict, **kwargs: object) -> None:
        # Server → client only; commands go through the REST API and its permissions.
        return

    async def mission_event(self, event: dict) -> None:
        await self.send_json(event["payload"])

"""`/ws/missions/<id>/`: a mission's live progress, for members of its organisation only."""

from __future__ import annotations

from typing import Any

from channels.db import database_sync_to_async

from fleet.consumers import GroupConsumer
from missions.live import group_name
from missions.models import Mission


@database_sync_to_async
def _visible(user, mission_id: str) -> bool:  # type: ignore[no-untyped-def]
    return Mission.objects.for_user(user).filter(pk=mission_id).exists()


class MissionConsumer(GroupConsumer):
    async def authorise(self, user: Any) -> str | None:
        mission_id = str(self.scope["url_route"]["kwargs"]["mission_id"])
        return mission_id if await _visible(user, mission_id) else None

    def group_for(self, mission_id: str) -> str:
        return group_name(mission_id)

    mission_event = GroupConsumer.send_payload

"""Resume paused missions the moment a drone of their organisation comes online."""

from __future__ import annotations

from typing import Any

from fleet.models import ConnectionEvent
from missions import tasks
from missions.models import Mission, MissionStatus


def drone_came_online(
    sender: type, instance: ConnectionEvent, created: bool, **kwargs: Any
) -> None:
    if not created or instance.kind != ConnectionEvent.Kind.ONLINE:
        return
    waiting = Mission.objects.filter(
        status=MissionStatus.PAUSED, organisation_id=instance.drone.organisation_id
    ).exists()
    if waiting:
        tasks.resume_paused.delay_on_commit()

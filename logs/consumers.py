"""Processing progress of one flight log, pushed to its page: server → client only."""

from __future__ import annotations

from typing import Any

from channels.db import database_sync_to_async

from fleet.consumers import CLOSE_NOT_FOUND, GroupConsumer
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


class LogProgressConsumer(GroupConsumer):
    """`/ws/logs/<uuid>/`: the log's status now, then every progress and status change."""

    # Outsiders learn nothing, not even that the log exists.
    refused_code = CLOSE_NOT_FOUND

    async def authorise(self, user: Any) -> FlightLog | None:
        return await _visible_log(user, str(self.scope["url_route"]["kwargs"]["log_id"]))

    def group_for(self, log: FlightLog) -> str:
        return log.group_name

    async def welcome(self, log: FlightLog) -> None:
        await self.send_json(await _snapshot(str(log.pk)))

    flightlog_event = GroupConsumer.send_payload

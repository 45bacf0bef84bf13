"""Push mission progress to the mission's page (one Channels group per mission)."""

from __future__ import annotations

import logging
from uuid import UUID

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer

log = logging.getLogger(__name__)


def group_name(mission_id: UUID | str) -> str:
    return f"mission-{mission_id}"


def push(mission_id: UUID | str, payload: dict) -> None:
    """Best effort: a page that misses a push reloads the state from the API."""
    layer = get_channel_layer()
    if layer is None:
        return
    try:
        async_to_sync(layer.group_send)(
            group_name(mission_id), {"type": "mission.event", "payload": payload}
        )
    except Exception:  # noqa: BLE001 - Redis away must never fail a progress update
        log.warning("could not push to mission %s", mission_id, exc_info=True)

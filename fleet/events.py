"""Push a change to every portal page of an organisation (the Channels group)."""

from __future__ import annotations

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer


def publish_to_organisation(organisation_id: int, payload: dict) -> None:
    layer = get_channel_layer()
    if layer is None:
        return
    async_to_sync(layer.group_send)(
        f"org-{organisation_id}", {"type": "fleet.event", "payload": payload}
    )

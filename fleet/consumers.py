"""Live fleet updates for the portal: one group per organisation, server → client only."""

from __future__ import annotations

from channels.db import database_sync_to_async
from channels.generic.websocket import AsyncJsonWebsocketConsumer

from .models import Drone, Membership
from .serializers import DroneSerializer


@database_sync_to_async
def _membership(user, slug: str | None) -> Membership | None:  # type: ignore[no-untyped-def]
    memberships = Membership.objects.for_user(user)
    if slug:
        memberships = memberships.filter(organisation__slug=slug)
    return memberships.first()


@database_sync_to_async
def _snapshot(organisation_id: int) -> list[dict]:
    drones = Drone.objects.filter(organisation_id=organisation_id).select_related("organisation")
    return list(DroneSerializer(drones, many=True).data)


class FleetConsumer(AsyncJsonWebsocketConsumer):
    """`/ws/fleet/?org=<slug>`: the organisation's drones, then every change as it happens."""

    group: str | None = None

    async def connect(self) -> None:
        user = self.scope.get("user")
        if user is None or not user.is_authenticated:
            await self.close(code=4401)
            return
        query = dict(
            part.split("=", 1)
            for part in self.scope.get("query_string", b"").decode().split("&")
            if "=" in part
        )
        membership = await _membership(user, query.get("org"))
        if membership is None:
            await self.close(code=4403)
            return
        self.group = membership.organisation.group_name
        await self.channel_layer.group_add(self.group, self.channel_name)
        await self.accept()
        await self.send_json(
            {"type": "snapshot", "drones": await _snapshot(membership.organisation_id)}
        )

    async def disconnect(self, code: int) -> None:
        if self.group:
            await self.channel_layer.group_discard(self.group, self.channel_name)

    async def receive_json(self, content: dict, **kwargs: object) -> None:
        # Clients only listen here; commands go through the REST API with its permissions.
        return

    async def fleet_event(self, event: dict) -> None:
        """Any `{"type": "fleet.event", "payload": {...}}` sent to the organisation's group."""
        await self.send_json(event["payload"])

"""Websocket consumers on channel-layer groups, and the portal's live fleet updates.

`GroupConsumer` is the one connect sequence every live page shares: an authenticated user
only, then what that user may watch (else the socket closes), join its group, accept,
send the first state; leave the group on disconnect. Origin and session checks happen
before any consumer runs (config/asgi.py).
"""

from __future__ import annotations

from typing import Any

from channels.db import database_sync_to_async
from channels.generic.websocket import AsyncJsonWebsocketConsumer

from .models import Drone, Membership
from .serializers import DroneSerializer

# Close codes: not signed in, and not allowed. Pages whose object's existence is private
# answer "not found" for both "not yours" and "does not exist".
CLOSE_UNAUTHENTICATED = 4401
CLOSE_FORBIDDEN = 4403
CLOSE_NOT_FOUND = 4404


def user_group(user_id: int) -> str:
    """Every open socket of one user: told to close when their access changes (a
    reconnecting page is then authorised anew)."""
    return f"user-{user_id}"


class GroupConsumer(AsyncJsonWebsocketConsumer):
    """A server → client socket on one group; subclasses say what a user may watch."""

    group: str | None = None
    user_group: str | None = None
    refused_code = CLOSE_FORBIDDEN

    async def authorise(self, user: Any) -> Any | None:
        """What this socket shows to `user` (from the URL), or None to refuse it."""
        raise NotImplementedError

    def group_for(self, target: Any) -> str:
        """The channel-layer group whose events this socket passes on."""
        raise NotImplementedError

    async def joined(self, target: Any) -> None:
        """Set-up once in the group, before the socket is accepted."""

    async def welcome(self, target: Any) -> None:
        """The first messages after accepting: the state now, read after joining the group
        so no change between the two is lost."""

    async def connect(self) -> None:
        user = self.scope.get("user")
        if user is None or not user.is_authenticated:
            await self.close(code=CLOSE_UNAUTHENTICATED)
            return
        target = await self.authorise(user)
        if target is None:
            await self.close(code=self.refused_code)
            return
        self.group = self.group_for(target)
        self.user_group = user_group(user.pk)
        await self.channel_layer.group_add(self.group, self.channel_name)
        await self.channel_layer.group_add(self.user_group, self.channel_name)
        await self.joined(target)
        await self.accept()
        await self.welcome(target)

    async def disconnect(self, code: int) -> None:
        for group in (self.group, self.user_group):
            if group:
                await self.channel_layer.group_discard(group, self.channel_name)

    async def receive_json(self, content: Any, **kwargs: object) -> None:
        # Clients only listen; commands go through the REST API with its permissions.
        return

    async def access_changed(self, event: dict) -> None:
        """`{"type": "access.changed"}` on the user's group: membership removed."""
        await self.close(code=CLOSE_FORBIDDEN)

    async def send_payload(self, event: dict) -> None:
        """A `{"type": ..., "payload": {...}}` group event, passed on as its payload."""
        await self.send_json(event["payload"])


@database_sync_to_async
def _membership(user, slug: str | None) -> Membership | None:  # type: ignore[no-untyped-def]
    memberships = Membership.objects.for_user(user)
    if slug:
        memberships = memberships.filter(organisation__slug=slug)
    return memberships.first()


async def membership_for_query(user: Any, scope: dict) -> Membership | None:
    """The user's membership in `?org=<slug>`, else their first one."""
    query = dict(
        part.split("=", 1)
        for part in scope.get("query_string", b"").decode().split("&")
        if "=" in part
    )
    return await _membership(user, query.get("org"))


@database_sync_to_async
def _snapshot(organisation_id: int) -> list[dict]:
    drones = Drone.objects.filter(organisation_id=organisation_id).select_related("organisation")
    return list(DroneSerializer(drones, many=True).data)


class FleetConsumer(GroupConsumer):
    """`/ws/fleet/?org=<slug>`: the organisation's drones, then every change as it happens."""

    async def authorise(self, user: Any) -> Membership | None:
        return await membership_for_query(user, self.scope)

    def group_for(self, membership: Membership) -> str:
        return membership.organisation.group_name

    async def welcome(self, membership: Membership) -> None:
        await self.send_json(
            {"type": "snapshot", "drones": await _snapshot(membership.organisation_id)}
        )

    # Any `{"type": "fleet.event", "payload": {...}}` sent to the organisation's group.
    fleet_event = GroupConsumer.send_payload

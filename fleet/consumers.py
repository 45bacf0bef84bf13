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

from .listing import marker_columns
from .models import Drone, Membership
from .serializers import DroneSerializer
from .state import describe

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


def query_of(scope: dict) -> dict[str, str]:
    """The socket URL's query parameters."""
    return dict(
        part.split("=", 1)
        for part in scope.get("query_string", b"").decode().split("&")
        if "=" in part
    )


async def membership_for_query(user: Any, scope: dict) -> Membership | None:
    """The user's membership in `?org=<slug>`, else their first one."""
    return await _membership(user, query_of(scope).get("org"))


# A socket may follow at most this many named drones (a page of a table).
MAX_NAMED_DRONES = 500


@database_sync_to_async
def _named_drones(organisation_id: int, drone_ids: set[str]) -> list[dict]:
    drones = Drone.objects.filter(organisation_id=organisation_id, drone_id__in=drone_ids)
    return [describe(dict(d)) for d in DroneSerializer(drones, many=True).data]


# Up to this many drones the first message carries each in full; a bigger fleet gets the
# map's columns only (the table pages through the table API instead).
FULL_SNAPSHOT_LIMIT = 200


@database_sync_to_async
def _fleet_snapshot(organisation_id: int) -> dict:
    drones = Drone.objects.filter(organisation_id=organisation_id)
    if drones.count() <= FULL_SNAPSHOT_LIMIT:
        full = [describe(dict(d)) for d in DroneSerializer(drones, many=True).data]
        return {"type": "snapshot", "drones": full}
    return {"type": "snapshot", "drones": [], "markers": marker_columns(organisation_id)}


def changed_fields(before: dict | None, after: dict) -> dict:
    """What of `after` differs from `before` (all of it when nothing was sent yet); the
    drone id always, so a client knows whose change it is."""
    if before is None:
        return dict(after)
    diff = {k: v for k, v in after.items() if before.get(k, _MISSING) != v}
    return {"drone_id": after["drone_id"], **diff} if diff else {}


_MISSING = object()


class FleetConsumer(GroupConsumer):
    """`/ws/fleet/?org=<slug>[&drone=<id>,<id>…]`: the organisation's drones as compact
    marker columns (or the named drones in full), then each change as only the fields that
    changed since this socket last heard of the drone; with `drone`, also their commands."""

    drone_ids: set[str] | None = None

    async def authorise(self, user: Any) -> Membership | None:
        query = query_of(self.scope)
        named = [d for d in query.get("drone", "").split(",") if d][:MAX_NAMED_DRONES]
        self.drone_ids = set(named) or None
        self.sent: dict[str, dict] = {}
        return await _membership(user, query.get("org"))

    def group_for(self, membership: Membership) -> str:
        return membership.organisation.group_name

    async def welcome(self, membership: Membership) -> None:
        if self.drone_ids is None:
            snapshot = await _fleet_snapshot(membership.organisation_id)
            for drone in snapshot["drones"]:
                self.sent[drone["drone_id"]] = drone
            await self.send_json(snapshot)
            return
        drones = await _named_drones(membership.organisation_id, self.drone_ids)
        for drone in drones:
            self.sent[drone["drone_id"]] = drone
        await self.send_json({"type": "snapshot", "drones": drones})

    async def fleet_event(self, event: dict) -> None:
        """Any `{"type": "fleet.event", "payload": {...}}` sent to the organisation's group:
        drone changes as diffs, commands to the page of their drone, the rest as it is."""
        payload = event["payload"]
        kind = payload.get("type")
        if kind == "command":
            if self.drone_ids is not None and payload.get("drone_id") in self.drone_ids:
                await self.send_json(payload)
            return
        drone = payload.get("drone")
        if kind != "drone" or not isinstance(drone, dict) or "drone_id" not in drone:
            await self.send_json(payload)
            return
        drone_id = drone["drone_id"]
        if self.drone_ids is not None and drone_id not in self.drone_ids:
            return
        before = self.sent.get(drone_id)
        diff = changed_fields(before, drone)
        if diff:
            self.sent[drone_id] = {**(before or {}), **drone}
            await self.send_json({"type": "drone", "drone": diff})

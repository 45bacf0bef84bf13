"""`/ws/missions/<id>/`: a mission's live progress, for members of its organisation only.

Besides the mission's own events, the socket follows the live state of the mission's
drones (from the organisation's fleet group) and sends, per drone, where it is and its
progress estimate (missions.estimates) as each heartbeat arrives."""

from __future__ import annotations

from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings

from fleet.consumers import GroupConsumer
from fleet.models import Drone
from fleet.state import describe
from missions.estimates import DroneRoute, mission_routes
from missions.live import group_name
from missions.models import Mission

# What of a drone's live state the mission page draws.
LIVE_FIELDS = ("drone_id", "position", "heading", "state", "battery", "ground_speed")


@database_sync_to_async
def _visible(user, mission_id: str) -> tuple[str, str] | None:  # type: ignore[no-untyped-def]
    """The mission's id and its organisation's fleet group, when `user` may see it."""
    mission = Mission.objects.for_user(user).filter(pk=mission_id).select_related("organisation")
    found = mission.first()
    return None if found is None else (mission_id, found.organisation.group_name)


@database_sync_to_async
def _routes(mission_id: str) -> dict[str, DroneRoute]:
    return mission_routes(mission_id)


@database_sync_to_async
def _drones(drone_ids: list[str]) -> list[dict]:
    drones = Drone.objects.filter(drone_id__in=drone_ids)
    return [describe({"drone_id": d.drone_id, **_model_fields(d), "home": d.home}) for d in drones]


def _model_fields(drone: Drone) -> dict:
    return {
        "online": drone.online,
        "armed": drone.armed,
        "airborne": drone.airborne,
        "flight_mode": drone.flight_mode,
        "position": drone.position,
        "battery": drone.battery,
    }


class MissionConsumer(GroupConsumer):
    async def authorise(self, user: Any) -> tuple[str, str] | None:
        mission_id = str(self.scope["url_route"]["kwargs"]["mission_id"])
        return await _visible(user, mission_id)

    def group_for(self, target: tuple[str, str]) -> str:
        return group_name(target[0])

    async def joined(self, target: tuple[str, str]) -> None:
        self.mission_id = target[0]
        self.fleet_group = target[1]
        self.live: dict[str, dict] = {}
        self.routes = await _routes(self.mission_id)
        await self.channel_layer.group_add(self.fleet_group, self.channel_name)

    async def welcome(self, target: tuple[str, str]) -> None:
        for drone in await _drones(list(self.routes)):
            self.live[drone["drone_id"]] = drone
        await self.send_progress(list(self.routes))

    async def disconnect(self, code: int) -> None:
        if getattr(self, "fleet_group", None):
            await self.channel_layer.group_discard(self.fleet_group, self.channel_name)
        await super().disconnect(code)

    async def send_progress(self, drone_ids: list[str]) -> None:
        reserve = settings.MISSIONS_BATTERY_RESERVE
        drones = []
        for drone_id in drone_ids:
            route, live = self.routes.get(drone_id), self.live.get(drone_id, {})
            if route is None:
                continue
            remaining = (live.get("battery") or {}).get("remaining")
            drain = live.get("battery_drain_per_s")
            drones.append(
                {
                    "live": {k: live.get(k) for k in (*LIVE_FIELDS, "home") if k in live},
                    "progress": route.progress(live.get("position"), remaining, drain, reserve),
                }
            )
        if drones:
            await self.send_json({"type": "progress", "drones": drones})

    async def mission_event(self, event: dict) -> None:
        """The mission's own events, passed on; a step or assignment change re-reads the
        routes, so the progress follows."""
        await self.send_json(event["payload"])
        if event["payload"].get("type") == "event":
            self.routes = await _routes(self.mission_id)
            await self.send_progress(list(self.routes))

    async def fleet_event(self, event: dict) -> None:
        payload = event["payload"]
        drone = payload.get("drone") if payload.get("type") == "drone" else None
        if not isinstance(drone, dict) or drone.get("drone_id") not in self.routes:
            return
        drone_id = drone["drone_id"]
        self.live[drone_id] = {**self.live.get(drone_id, {}), **drone}
        await self.send_progress([drone_id])

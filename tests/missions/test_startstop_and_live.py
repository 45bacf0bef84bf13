"""`/control` startchain/stopchain creating tracked missions, and the mission websocket."""

from __future__ import annotations

import base64
import json

import pytest
from asgiref.sync import async_to_sync, sync_to_async
from channels.routing import URLRouter
from channels.testing import WebsocketCommunicator
from django.test import Client

from config.routing import websocket_urlpatterns
from missions import live
from missions.models import Mission, MissionStatus

from .conftest import online_drone, point_at


def _chain(steps: object) -> str:
    return base64.b64encode(json.dumps(steps).encode()).decode()


def _client(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def test_startchain_on_control_creates_and_starts_a_tracked_mission(
    world, outbox, django_capture_on_commit_callbacks
):
    online_drone(world.org, "ACME_1")
    lat, lon = point_at(30, 0)
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 5}},
        {"command": "navigate", "params": {"lat": lat, "lon": lon}},
    ]
    with django_capture_on_commit_callbacks(execute=True):
        response = _client(world.operator).post(
            "/control", {"command": "startchain", "droneID": "ACME_1", "mission": _chain(steps)}
        )
    assert response.status_code == 200, response.content
    result = response.json()["result"]
    mission = Mission.objects.get(pk=result["mission_id"])
    assert mission.status == MissionStatus.RUNNING and mission.steps.count() == 3
    assert mission.assignments.get().drone.drone_id == "ACME_1"
    [item] = outbox.items()
    assert item["topic"] == "ACME_1/mission/in"
    assert item["payload"]["mission_id"] == result["mission_id"]

    with django_capture_on_commit_callbacks(execute=True):
        stopped = _client(world.operator).post(
            "/control", {"command": "stopchain", "droneID": "ACME_1"}
        )
    assert stopped.status_code == 200, stopped.content
    mission.refresh_from_db()
    assert mission.status == MissionStatus.STOPPED
    assert outbox.items()[-1]["payload"]["action"] == "stop"


def test_startchain_with_an_unknown_command_is_refused_and_starts_nothing(world, outbox):
    online_drone(world.org, "ACME_1")
    response = _client(world.operator).post(
        "/control",
        {"command": "startchain", "droneID": "ACME_1", "mission": _chain([{"command": "warp"}])},
    )
    assert response.status_code == 400
    assert "steps[0].command" in response.json()["error"]
    assert not Mission.objects.exists() and outbox.items() == []


def test_stopchain_without_a_running_mission_is_a_conflict(world, outbox):
    online_drone(world.org, "ACME_1")
    response = _client(world.operator).post(
        "/control", {"command": "stopchain", "droneID": "ACME_1"}
    )
    assert response.status_code == 409


def _communicator(mission_id: str, user) -> WebsocketCommunicator:  # type: ignore[no-untyped-def]
    communicator = WebsocketCommunicator(
        URLRouter(websocket_urlpatterns), f"/ws/missions/{mission_id}/"
    )
    communicator.scope["user"] = user
    return communicator


@pytest.mark.django_db(transaction=True)
def test_the_mission_websocket_pushes_progress_to_members_and_refuses_outsiders(world_tx):
    mission = Mission.objects.create(organisation=world_tx.org, name="live")

    async def scenario() -> tuple[dict, tuple]:
        member = _communicator(str(mission.pk), world_tx.viewer)
        connected, _ = await member.connect()
        assert connected
        await sync_to_async(live.push)(mission.pk, {"type": "mission", "status": "running"})
        received = await member.receive_json_from(timeout=5)
        await member.disconnect()

        outsider = _communicator(str(mission.pk), world_tx.outsider)
        refused = await outsider.connect()
        await outsider.disconnect()
        return received, refused

    received, refused = async_to_sync(scenario)()
    assert received == {"type": "mission", "status": "running"}
    assert refused == (False, 4403)

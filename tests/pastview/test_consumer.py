"""The past-view websocket and settings API: organisation isolation, roles, teleoperation
through the Drone Manager, and what a page gets when it connects."""

from __future__ import annotations

import asyncio
import json

import pytest
from channels.testing import WebsocketCommunicator
from rest_framework.test import APIClient

from tests.support.websocket import connect_websocket

from .support import in_own_loop

pytestmark = [
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]


async def connect(user, drone_id: str = "ACME_1") -> tuple[WebsocketCommunicator, bool, int]:  # type: ignore[no-untyped-def]
    return await connect_websocket(f"/ws/pastview/{drone_id}/", user)  # type: ignore[return-value]


async def push(drone_id: str, message: dict) -> None:
    from channels.layers import get_channel_layer

    from pastview.service import group_name

    await get_channel_layer().group_send(
        group_name(drone_id), {"type": "pastview.message", "message": message}
    )


LIVE = {"type": "live", "ts": 1.0, "jpeg": "", "pose": None}


def update(yaw_quaternion: list[float] | None = None) -> dict:
    return {
        "type": "update",
        "ts": 1.0,
        "tracking": "tracked",
        "event": None,
        "pose": {"position": [0.0, 0.0, -10.0], "orientation": yaw_quaternion or [0, 0, 0, 1]},
        "function": "spirit",
        "frame": None,
        "changed": False,
        "jpeg": None,
        "relative": None,
    }


@in_own_loop
async def test_anonymous_visitors_are_refused(world_tx):
    communicator, connected, code = await connect(None)
    assert not connected and code == 4401
    await communicator.disconnect()


@in_own_loop
async def test_another_organisations_drone_is_as_unknown_as_none(world_tx):
    communicator, connected, code = await connect(world_tx.outsider, "ACME_1")
    assert not connected and code == 4404
    await communicator.disconnect()
    communicator, connected, code = await connect(world_tx.owner, "GLOBEX_1")
    assert not connected and code == 4404
    await communicator.disconnect()


@in_own_loop
async def test_a_member_gets_the_settings_then_the_drones_updates_only(world_tx):
    mine, connected, _ = await connect(world_tx.viewer, "ACME_1")
    theirs, their_connected, _ = await connect(world_tx.outsider, "GLOBEX_1")
    assert connected and their_connected
    try:
        hello = await mine.receive_json_from(timeout=5)
        assert hello["type"] == "hello" and hello["can_operate"] is False
        assert hello["settings"]["evaluation"]["function"] == "spirit"
        assert hello["settings"]["camera"] == {"fov_deg": 90.0, "pitch_down_deg": 30.0}
        await theirs.receive_json_from(timeout=5)  # their hello
        await push("ACME_1", update())
        assert (await mine.receive_json_from(timeout=5))["type"] == "update"
        assert await theirs.receive_nothing(timeout=0.3)
    finally:
        await mine.disconnect()
        await theirs.disconnect()


@in_own_loop
async def test_a_page_that_connects_gets_the_last_snapshot_at_once(world_tx):
    import redis.asyncio as aredis
    from django.conf import settings

    from pastview.runner import snapshot_key

    snapshot = {"update": {**update(), "jpeg": "AAAA"}, "live": None, "status": {}}
    client = aredis.Redis.from_url(settings.REDIS_URL)
    await client.set(snapshot_key("ACME_1"), json.dumps(snapshot), ex=30)
    communicator, connected, _ = await connect(world_tx.viewer)
    try:
        await communicator.receive_json_from(timeout=5)  # hello
        got = await communicator.receive_json_from(timeout=5)
        assert got["type"] == "snapshot" and got["update"]["jpeg"] == "AAAA"
    finally:
        await communicator.disconnect()
        await client.delete(snapshot_key("ACME_1"))
        await client.aclose()


@in_own_loop
async def test_a_viewer_cannot_teleoperate(world_tx):
    communicator, connected, _ = await connect(world_tx.viewer)
    try:
        await communicator.receive_json_from(timeout=5)
        await communicator.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        reply = await communicator.receive_json_from(timeout=5)
        assert reply == {
            "type": "teleop",
            "ok": False,
            "error": "Only operators and admins may command drones.",
            "sent": [],
        }
    finally:
        await communicator.disconnect()


@in_own_loop
async def test_an_operators_move_goes_through_the_drone_manager(world_tx):
    from asgiref.sync import sync_to_async

    from fleet.models import CommandLog

    communicator, connected, _ = await connect(world_tx.operator)
    try:
        hello = await communicator.receive_json_from(timeout=5)
        assert hello["can_operate"] is True
        await communicator.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        reply = await communicator.receive_json_from(timeout=5)
        assert reply["ok"] is False and "heading" in reply["error"]
        await push("ACME_1", update([0.0, 0.0, 0.7071068, 0.7071068]))  # facing east
        await communicator.receive_json_from(timeout=5)
        await communicator.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        reply = await communicator.receive_json_from(timeout=5)
        # A heading but no camera frame and no tracked pose on a frame: no current view.
        assert reply["ok"] is False and "No camera frame" in reply["error"]
        await push("ACME_1", LIVE)
        await push("ACME_1", {**update([0.0, 0.0, 0.7071068, 0.7071068]), "frame": {"id": 1}})
        for _ in range(2):
            await communicator.receive_json_from(timeout=5)
        await communicator.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        reply = await communicator.receive_json_from(timeout=5)
        # The world's drone is offline: the Drone Manager refuses, and logs who tried what.
        assert reply["ok"] is False and reply["error"] == "Drone ACME_1 is offline."
        log = await sync_to_async(lambda: list(CommandLog.objects.values("command", "params")))()
        assert log == [{"command": "changeE", "params": {"value": 0.5}}]
    finally:
        await communicator.disconnect()


@in_own_loop
async def test_malformed_teleop_input_is_answered_not_sent(world_tx):
    communicator, connected, _ = await connect(world_tx.operator)
    try:
        await communicator.receive_json_from(timeout=5)
        await communicator.send_json_to({"type": "teleop", "forward": "fast"})
        assert "forward must be a number" in (await communicator.receive_json_from(5))["error"]
        await communicator.send_json_to({"type": "teleop", "forward": 3})
        assert "within -1..1" in (await communicator.receive_json_from(5))["error"]
        await communicator.send_json_to(["not", "an", "object"])
        assert (await communicator.receive_json_from(5))["error"] == "Unknown message type."
    finally:
        await communicator.disconnect()


def api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def test_members_read_the_settings_and_outsiders_get_404(world_tx):
    assert api(world_tx.viewer).get("/pastview/api/ACME_1/settings/").status_code == 200
    response = api(world_tx.outsider).get("/pastview/api/ACME_1/settings/")
    assert response.status_code == 404 and response.json()["error"]


def test_only_operators_change_the_settings(world_tx):
    body = {"evaluation": {"function": "murata", "coeff_tilt": 3}}
    response = api(world_tx.viewer).put("/pastview/api/ACME_1/settings/", body, format="json")
    assert response.status_code == 403 and response.json()["code"] == "permission_denied"
    response = api(world_tx.operator).put("/pastview/api/ACME_1/settings/", body, format="json")
    assert response.status_code == 200
    assert response.json()["evaluation"]["function"] == "murata"
    assert response.json()["evaluation"]["coeff_tilt"] == 3.0
    again = api(world_tx.viewer).get("/pastview/api/ACME_1/settings/").json()
    assert again["evaluation"]["coeff_tilt"] == 3.0


def test_bad_settings_are_refused_with_the_reason(world_tx):
    operator = api(world_tx.operator)
    for body, words in (
        ({"evaluation": {"function": "magic"}}, "unknown evaluation function"),
        ({"evaluation": {"function": "spirit", "coeff_distance": -1}}, "must not be negative"),
        ({"evaluation": {"function": "spirit", "coeff_distance": "x"}}, "must be a number"),
        ({"capacity": 0}, "capacity"),
        ({"camera": {"fov_deg": 400}}, "camera.fov_deg"),
    ):
        response = operator.put("/pastview/api/ACME_1/settings/", body, format="json")
        assert response.status_code == 400, body
        assert words in response.json()["error"], response.json()


def test_the_page_shows_controls_to_operators_only(client, world_tx):
    client.force_login(world_tx.operator)
    page = client.get("/pastview/ACME_1/")
    assert page.status_code == 200 and b'id="pv-teleop"' in page.content
    client.force_login(world_tx.viewer)
    page = client.get("/pastview/ACME_1/")
    assert page.status_code == 200 and b'id="pv-teleop"' not in page.content
    assert client.get("/pastview/GLOBEX_1/").status_code == 404


def test_the_drawn_box_has_the_frames_proportions():
    from pastview.views import frame_box

    box = frame_box({"FRAME_SIZE": "550"})
    assert box["length"] == box["width"] == pytest.approx(0.55 / 2**0.5)
    assert box["height"] == pytest.approx(box["width"] / 5)
    assert frame_box({"FRAME_SIZE": "huge"}) == frame_box({})


@in_own_loop
async def test_moves_stop_when_the_frames_stop(world_tx, settings):
    from asgiref.sync import sync_to_async

    from fleet.models import CommandLog

    settings.PASTVIEW_TELEOP_FRESH_S = 0.5
    communicator, connected, _ = await connect(world_tx.operator)
    try:
        await communicator.receive_json_from(timeout=5)
        await push("ACME_1", LIVE)
        await push("ACME_1", {**update(), "frame": {"id": 1}})
        for _ in range(2):
            await communicator.receive_json_from(timeout=5)
        await asyncio.sleep(0.7)  # no frame since: the view is stale
        await communicator.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        reply = await communicator.receive_json_from(timeout=5)
        assert reply["ok"] is False and "in the last 0.5 s" in reply["error"]
        assert not await sync_to_async(CommandLog.objects.exists)()
    finally:
        await communicator.disconnect()

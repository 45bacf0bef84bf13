"""End to end: a simulated drone (the flight-controller simulator over a pty, the onboard
agent with its camera and pose stream) flies a square; the past-view service, the
gateway and the websocket deliver frames and relative poses, and an operator's
teleoperation moves the drone through the Drone Manager."""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from runtime.processes import wait_for
from tests.onboard.ground import Ground, start_agent
from workers.mosquitto import start_broker

from .support import ServiceThread, in_own_loop
from .test_consumer import connect

pytestmark = [
    pytest.mark.e2e,
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]

DRONE = "ACME_1"  # the world's drone, so the portal knows it
HOME = (40.6303, -8.6575, 12.0)
SCALE = 4.0
SIDE_M = 8.0


@pytest.fixture
def broker(tmp_path: Path):
    b = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    yield b
    b.stop()


@pytest.fixture
def drone(tmp_path: Path, broker):
    """The simulator and the agent process, with a 10 Hz camera and a 50 Hz pose stream."""
    sim = start_simulator(
        home=HOME,
        time_scale=SCALE,
        arming_line=tmp_path / "arming_line",
        log_file=tmp_path / "sim.log",
    )
    agent = start_agent(
        tmp_path,
        drone_id=DRONE,
        link=sim.url,
        broker_url=broker.url_for(DRONE),
        arming_line=tmp_path / "arming_line",
        time_scale=SCALE,
        extra=["--video-rate", "10", "--pose-rate", "50"],
    )
    yield agent
    agent.stop()
    sim.stop()


@pytest.fixture
def ground_services(broker, world_tx, settings):
    """The past-view service and a gateway (for the Drone Manager's replies), in threads."""
    # Commands are queued for the gateway of the broker the settings name: this one.
    settings.MQTT_URL = broker.url_for("ground")
    from pastview.models import ViewSettings
    from workers.gateway import Gateway

    # The camera sends 10 frames a second here: keep them all (the default keeps 2).
    ViewSettings.objects.create(drone=world_tx.drone, settings={"video_hz": 0})
    service = ServiceThread(broker.url_for("ground"))
    gateway = Gateway(broker.url_for("ground"), client_id="pastview-e2e-gateway")
    gateway.start()
    assert gateway.wait_connected(10)
    yield service
    gateway.stop()
    service.stop()


async def updates_until(communicator, done, timeout: float) -> list[dict]:  # type: ignore[no-untyped-def]
    seen: list[dict] = []
    deadline = time.monotonic() + timeout
    while not done(seen):
        left = deadline - time.monotonic()
        assert left > 0, f"only {len(seen)} updates; last: {seen[-1:]}"
        message = await communicator.receive_json_from(timeout=left)
        if message["type"] in ("update", "snapshot"):
            seen.append(message if message["type"] == "update" else message["update"])
    return seen


@in_own_loop
async def test_a_square_flight_reaches_the_page_as_frames_and_relative_poses(
    drone, broker, ground_services, world_tx
):
    from asgiref.sync import sync_to_async

    ground = Ground(broker.port, DRONE, password="pw", client_id="pastview-e2e-ground")
    page, connected, _ = await connect(world_tx.operator)
    try:
        assert connected
        assert (await page.receive_json_from(timeout=5))["type"] == "hello"
        await sync_to_async(ground.wait_for)(
            "heartbeats", lambda m: m["fc"]["connected"] and m["position"] is not None, 30
        )
        assert (await sync_to_async(ground.command)("arm"))["ok"]
        assert (await sync_to_async(ground.command)("takeoff", altitude=10))["ok"]
        await sync_to_async(ground.wait_for)(
            "heartbeats", lambda m: m["position"] is not None and m["position"]["alt"] > 9.0
        )

        def near(n: float, e: float):  # type: ignore[no-untyped-def]
            def check(seen: list[dict]) -> bool:
                north, east, _ = seen[-1]["pose"]["position"] if seen else (None, None, None)
                return bool(seen) and math.hypot(north - n, east - e) < 0.5

            return check

        # Each leg once the last is flown: relative moves add to the last target.
        seen: list[dict] = []
        legs: list[int] = []
        for command, value, corner in (
            ("changeN", SIDE_M, (SIDE_M, 0.0)),
            ("changeE", SIDE_M, (SIDE_M, SIDE_M)),
            ("changeN", -SIDE_M, (0.0, SIDE_M)),
            ("changeE", -SIDE_M, (0.0, 0.0)),
        ):
            assert (await sync_to_async(ground.command)(command, value=value))["ok"]
            legs.append(len(seen))
            seen += await updates_until(page, near(*corner), timeout=30)
        with_frame = [u for u in seen if u["frame"] is not None]
        assert with_frame, "no update carried a frame"
        # A frame's image comes exactly when the choice changes, never with a repeat.
        previous = None
        for u in with_frame:
            changed = previous is None or u["frame"]["id"] != previous
            assert u["changed"] is changed and bool(u["jpeg"]) is changed
            previous = u["frame"]["id"]
        for u in with_frame:
            position = u["relative"]["position"]
            assert all(math.isfinite(v) for v in position)
            assert math.isclose(sum(c * c for c in u["relative"]["orientation"]), 1.0, rel_tol=1e-6)
        assert len({u["frame"]["id"] for u in with_frame}) >= 4
        # The chosen frames show the drone ahead of the camera that took them.
        # Once the drone has flown a leg at altitude, the chosen frames show it ahead of
        # the camera that took them (during take-off it is above the frames instead).
        later = [u for u in seen[legs[1] :] if u["frame"]]
        ahead = [u for u in later if u["relative"]["position"][0] > 0]
        assert later and len(ahead) >= 0.85 * len(later), (len(ahead), len(later))
        tracked = [u for u in seen if u["tracking"] == "tracked"]
        assert len(tracked) > 0.9 * len(seen)

        # Teleoperation: one step forward, rotated by the heading, through the Drone Manager.
        await page.send_json_to({"type": "teleop", "forward": 1, "right": 0, "up": 0})
        while True:
            reply = await page.receive_json_from(timeout=20)
            if reply["type"] == "teleop":
                break
        assert reply["ok"], reply
        assert {s["command"] for s in reply["sent"]} <= {"changeN", "changeE"}
        step = math.hypot(*(s["value"] for s in reply["sent"]))
        assert step == pytest.approx(0.5, abs=0.01)
    finally:
        await page.disconnect()
        ground.close()
        await asyncio.sleep(0)


def rate(stamps: list[float]) -> float:
    return (len(stamps) - 1) / (stamps[-1] - stamps[0])


def test_the_agent_publishes_downsampled_frames_and_a_pose_stream(drone, broker):
    ground = Ground(broker.port, DRONE, password="pw", client_id="pastview-e2e-ground2")
    try:
        ground.wait_for("camera", lambda m: True, timeout=30)
        assert wait_for(lambda: len(ground.on("camera")) >= 11, timeout=10)
        frames = ground.on("camera")
        assert all(f["jpeg"].startswith("/9j/") for f in frames)  # base64 of a JPEG's SOI
        # Every third frame of the 30 Hz camera for the 10 Hz asked (fewer on a busy machine:
        # the camera skips ticks rather than bursting).
        assert 5.0 <= rate([f["ts"] for f in frames]) <= 11.0
        poses = [o for m in ground.on("telemetry") for o in m["objects"] if o["name"] == "Pose"]
        assert set(poses[0]["fields"]) == {"North", "East", "Down", "qx", "qy", "qz", "qw"}
        assert 30.0 <= rate([p["ts"] for p in poses]) <= 55.0
        # On the ground and idle, the simulated tracker still jitters: no false "lost".
        samples = [tuple(p["fields"].values()) for p in poses]
        assert all(a != b for a, b in zip(samples, samples[1:], strict=False))
    finally:
        ground.close()

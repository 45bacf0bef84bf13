"""The past-view service on a real broker: frames and poses in over MQTT, updates out on the
drone's Channels group (real Redis), bad input counted while the view keeps running."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from runtime.processes import wait_for
from workers.mosquitto import start_broker

from .support import DronePublisher, GroupListener, ServiceThread, close, in_own_loop, level

pytestmark = [
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]

DRONE = "ACME_1"  # the world's drone


@pytest.fixture
def broker(tmp_path: Path):
    b = start_broker(tmp_path, {"ground": "pw", DRONE: "dpw", "GLOBEX_1": "gpw"})
    yield b
    b.stop()


@pytest.fixture
def service(broker, world_tx):
    running = ServiceThread(broker.url_for("ground"))
    yield running
    running.stop()


@pytest.fixture
def drone(broker):
    publisher = DronePublisher(broker.port, DRONE, "dpw")
    yield publisher
    publisher.close()


@in_own_loop
async def test_a_pose_after_a_frame_reaches_the_page_with_the_frame_and_the_relative_pose(
    service, drone
):
    t0 = time.time()
    async with GroupListener(DRONE, service) as pages:
        drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
        live = await pages.next(lambda m: m["type"] == "live")
        assert live["ts"] == t0 and live["jpeg"]
        # 2.5 m straight ahead of where the frame was taken, same heading: SPIRIT's ideal.
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        update = await pages.next(lambda m: m["type"] == "update")
    assert update["tracking"] == "tracked"
    assert update["function"] == "spirit"
    assert update["changed"] is True and update["jpeg"]
    assert update["frame"]["ts"] == t0
    assert close(update["relative"]["position"], [2.5, 0.0, 0.0])
    assert close(update["relative"]["orientation"], [0.0, 0.0, 0.0, 1.0])


@in_own_loop
async def test_the_frame_image_is_sent_only_when_the_choice_changes(service, drone):
    t0 = time.time()
    async with GroupListener(DRONE, service) as pages:
        drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
        await pages.next(lambda m: m["type"] == "live")
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        first = await pages.next(lambda m: m["type"] == "update")
        # Poses 40 ms apart: the throttle (30 Hz) lets each through, the frame stays.
        for i in range(1, 4):
            time.sleep(0.04)
            drone.poses((t0 + 0.1 + i * 0.04, [2.5 + 0.01 * i, 0.0, -10.0], level(0.0)))
            again = await pages.next(lambda m: m["type"] == "update")
            assert again["frame"]["id"] == first["frame"]["id"]
            assert again["changed"] is False and again["jpeg"] is None
        # A frame taken 2.5 m behind the drone's new place wins and comes with its image.
        drone.frame(t0 + 1.0, [10.0, 0.0, -10.0], level(0.0))
        drone.poses((t0 + 1.1, [12.5, 0.0, -10.0], level(0.0)))
        switched = await pages.next(lambda m: m["type"] == "update" and m["changed"])
    assert switched["frame"]["id"] != first["frame"]["id"] and switched["jpeg"]
    assert close(switched["relative"]["position"], [2.5, 0.0, 0.0])


@in_own_loop
async def test_tracking_lost_and_found_are_pushed_when_they_happen(service, drone):
    t0 = time.time()
    still = [1.0, 2.0, -10.0]
    async with GroupListener(DRONE, service) as pages:
        drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
        drone.poses((t0 + 0.1, still, level(10.0)), (t0 + 0.2, still, level(10.0)))
        lost = await pages.next(lambda m: m.get("event") == "lost")
        drone.poses((t0 + 0.3, [1.0, 2.1, -10.0], level(10.0)))
        found = await pages.next(lambda m: m.get("event") == "found")
    assert lost["tracking"] == "lost"
    assert found["tracking"] == "tracked"


@in_own_loop
async def test_bad_input_is_counted_and_the_view_keeps_running(service, drone):
    t0 = time.time()
    drone.raw("camera", b"\xff\xfe not json")
    drone.raw("camera", json.dumps({"ts": t0, "pose": {"position": [0, 0, -10]}, "jpeg": "x"}))
    broken = b"\xff\xd8\xff\xe0" + b"\x00garbage" * 50 + b"\xff\xd9"
    drone.frame(t0, [0.0, 0.0, -10.0], level(0.0), jpeg=broken)
    drone.frame(t0 + 0.5, [5.0, 0.0, -10.0], level(0.0))
    drone.frame(t0 + 0.2, [9.0, 0.0, -10.0], level(0.0))  # older than the last: out of order
    drone.poses((t0 + 0.6, [7.5, 0.0, float("nan")], level(0.0)))
    drone.poses((t0 + 0.7, [7.5, 0.0, -10.0], [0.0, 0.0, 0.0, 2.0]))  # not a unit quaternion
    drone.poses((t0 + 0.65, [7.4, 0.0, -10.0], level(0.0)))  # older than the last pose
    drone.raw("telemetry", b'{"ts": 1, "objects": "nope"}')

    def counted() -> bool:
        status = service.service.status(DRONE)
        return bool(status) and status["poses_received"] == 3

    assert wait_for(counted)
    status = service.service.status(DRONE)
    assert status["frames_malformed"] == 1
    assert status["buffer"]["corrupt_jpeg"] == 1
    assert status["frames_out_of_order"] == 1
    assert status["poses_bad"] == 1
    assert status["quaternions_repaired"] == 1
    assert status["poses_out_of_order"] == 1
    assert status["frames_stored"] == 1
    counters = service.service.counters
    assert counters["dropped.malformed"] == 3  # not JSON, no jpeg, objects not a list
    async with GroupListener(DRONE, service) as pages:
        drone.poses((t0 + 0.8, [7.5, 0.0, -10.0], level(0.0)))
        update = await pages.next(lambda m: m["type"] == "update")
    assert close(update["relative"]["position"], [2.5, 0.0, 0.0])


@in_own_loop
async def test_settings_edited_in_the_database_switch_the_evaluation_function(
    service, drone, world_tx
):
    from asgiref.sync import sync_to_async

    from pastview.models import ViewSettings

    t0 = time.time()
    async with GroupListener(DRONE, service) as pages:
        drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        before = await pages.next(lambda m: m["type"] == "update")
        await sync_to_async(ViewSettings.objects.create)(
            drone=world_tx.drone,
            settings={"evaluation": {"function": "constant_time_delay", "ref_delay_s": 1.0}},
        )
        # The service looks every two seconds; looking now as well changes nothing else.
        await sync_to_async(service.process.reload_settings)()
        applied = await pages.next(lambda m: m["type"] == "settings")
        drone.poses((t0 + 0.2, [2.6, 0.0, -10.0], level(0.0)))
        after = await pages.next(lambda m: m["type"] == "update")
    assert before["function"] == "spirit"
    assert applied["settings"]["evaluation"]["function"] == "constant_time_delay"
    assert after["function"] == "constant_time_delay"
    assert after["frame"]["score"] == pytest.approx(0.8, abs=1e-6)


@in_own_loop
async def test_one_drones_frames_never_reach_another_drones_page(service, broker, drone):
    other = DronePublisher(broker.port, "GLOBEX_1", "gpw")
    try:
        async with (
            GroupListener("GLOBEX_1", service) as theirs,
            GroupListener(DRONE, service) as mine,
        ):
            drone.frame(time.time(), [0.0, 0.0, -10.0], level(0.0))
            await mine.next(lambda m: m["type"] == "live")
            with pytest.raises(AssertionError):
                await theirs.next(timeout=0.5)
            # A drone cannot publish into another's tree: the broker's ACL drops it.
            other.client.publish(f"{DRONE}/camera/out", b"{}", qos=1).wait_for_publish(5)
            assert service.service.counters["dropped.malformed"] == 0
    finally:
        other.close()


@pytest.fixture
def command_process(broker, world_tx, tmp_path: Path):
    """`manage.py pastview` as the platform runs it, on the test database and broker."""
    from django.db import connection

    env = dict(
        os.environ,
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=connection.settings_dict["NAME"],
        PYTHONUNBUFFERED="1",
    )
    with open(tmp_path / "pastview.log", "wb") as log:
        process = subprocess.Popen(
            [sys.executable, "manage.py", "pastview", "--broker", broker.url_for("ground")],
            cwd=Path(__file__).resolve().parents[2],
            env=env,
            stdout=subprocess.PIPE,
            stderr=log,
        )
    assert process.stdout is not None
    assert process.stdout.readline().startswith(b"pastview: 127.0.0.1:")
    yield process
    if process.poll() is None:
        process.kill()
        process.wait()


@in_own_loop
async def test_the_management_command_serves_pages_and_stops_on_sigterm(command_process, drone):
    async with GroupListener(DRONE, None) as pages:
        deadline = time.monotonic() + 10
        # The command subscribes, and reads the page's watch mark, shortly after it starts:
        # send until a frame gets through, each a new one (the page is sent a frame once).
        while True:
            t0 = time.time()
            drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
            try:
                await pages.next(lambda m: m["type"] == "live", timeout=0.5)
                break
            except AssertionError:
                assert time.monotonic() < deadline, "manage.py pastview never took a frame"
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        update = await pages.next(lambda m: m["type"] == "update")
    assert close(update["relative"]["position"], [2.5, 0.0, 0.0])
    # The operations page lists the process, with what it received, while it runs.
    mine = await _instance_of(command_process.pid, lambda i: i.counters.get("received", 0) >= 2)
    assert mine.alive and mine.process == "pastview"
    command_process.send_signal(signal.SIGTERM)
    assert command_process.wait(10) == 0
    assert b"pastview: stopped" in command_process.stdout.read()
    assert not (await _instance_of(command_process.pid, lambda i: not i.alive)).alive


async def _instance_of(pid: int, until, timeout: float = 5.0):  # type: ignore[no-untyped-def]
    """The `pastview` instance report of process `pid` once `until(instance)` holds."""
    from asgiref.sync import sync_to_async

    from workers.counters import instances

    deadline = time.monotonic() + timeout
    while True:
        found = [i for i in await sync_to_async(instances)() if i.process == "pastview"]
        mine = next((i for i in found if i.pid == pid), None)
        if mine is not None and until(mine):
            return mine
        assert time.monotonic() < deadline, f"no such pastview instance of {pid}: {found}"
        await asyncio.sleep(0.1)


@in_own_loop
async def test_a_drone_no_page_watches_is_evaluated_and_remembered_but_not_pushed(service, drone):
    from asgiref.sync import sync_to_async
    from channels.layers import get_channel_layer

    from pastview.runner import load_snapshot
    from pastview.service import group_name

    layer = get_channel_layer()
    channel = await layer.new_channel()
    await layer.group_add(group_name(DRONE), channel)  # listening, but no watch mark
    try:
        t0 = time.time()
        drone.frame(t0, [0.0, 0.0, -10.0], level(0.0))
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        for _ in range(100):
            status = service.service.status(DRONE)
            if status and status["poses_received"] == 1:
                break
            await asyncio.sleep(0.05)
        assert service.service.counters["unwatched"] >= 2  # the live frame and the update
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(layer.receive(channel), 0.5)
        snapshot = await sync_to_async(load_snapshot)(DRONE)
        assert snapshot["update"]["jpeg"] and snapshot["live"]["ts"] == t0
    finally:
        await layer.group_discard(group_name(DRONE), channel)


@in_own_loop
async def test_without_a_pose_stream_the_flight_controllers_attitude_and_position_are_used(
    service, drone
):
    t0 = time.time()
    yaw90 = level(90.0)  # (qx, qy, qz, qw); dRonin sends q1 = qw first
    attitude = {"q1": yaw90[3], "q2": yaw90[0], "q3": yaw90[1], "q4": yaw90[2]}
    async with GroupListener(DRONE, service) as pages:
        drone.frame(t0, [0.0, 0.0, -10.0], level(90.0))
        drone.raw(
            "telemetry",
            json.dumps(
                {
                    "ts": t0 + 0.1,
                    "objects": [
                        {"name": "PositionActual", "ts": t0 + 0.1,
                         "fields": {"North": 0.0, "East": 2.5, "Down": -10.0}},
                        {"name": "AttitudeActual", "ts": t0 + 0.1,
                         "fields": {**attitude, "Roll": 0.0, "Pitch": 0.0, "Yaw": 90.0}},
                        {"name": "FlightStatus", "ts": t0 + 0.1, "fields": {"Armed": "Armed"}},
                    ],
                }
            ),
        )  # fmt: skip
        update = await pages.next(lambda m: m["type"] == "update")
    assert close(update["pose"]["orientation"], yaw90)
    assert close(update["relative"]["position"], [2.5, 0.0, 0.0])

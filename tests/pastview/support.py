"""Helpers for the past-view live tests: a drone publishing frames and poses over MQTT, a
listener on a drone's Channels group, and the service process run in a thread."""

from __future__ import annotations

import asyncio
import base64
import functools
import json
import math
import threading
import time
from typing import Any

import paho.mqtt.client as paho
from paho.mqtt.enums import CallbackAPIVersion

from onboard.synthetic_camera import orientation_from_euler, render_view


def level(yaw_deg: float) -> list[float]:
    return list(orientation_from_euler(0.0, 0.0, yaw_deg))


class DronePublisher:
    """Publishes as the drone itself (its broker credentials), QoS 1 so nothing is lost."""

    def __init__(self, port: int, drone_id: str, password: str) -> None:
        self.drone_id = drone_id
        self.client = paho.Client(CallbackAPIVersion.VERSION2, client_id=f"test-{drone_id}")
        self.client.username_pw_set(drone_id, password)
        self.client.connect("127.0.0.1", port, keepalive=10)
        self.client.loop_start()

    def raw(self, channel: str, payload: bytes | str) -> None:
        info = self.client.publish(f"{self.drone_id}/{channel}/out", payload, qos=1)
        info.wait_for_publish(5)

    def frame(
        self,
        ts: float,
        position: list[float],
        orientation: list[float],
        jpeg: bytes | None = None,
    ) -> None:
        if jpeg is None:
            jpeg = render_view(tuple(position), tuple(orientation), width=160, height=120)
        message = {
            "ts": ts,
            "pose": {"position": position, "orientation": orientation},
            "jpeg": base64.b64encode(jpeg).decode("ascii"),
        }
        self.raw("camera", json.dumps(message))

    def poses(self, *samples: tuple[float, list[float], list[float]]) -> None:
        objects = [
            {
                "name": "Pose",
                "ts": ts,
                "fields": {
                    "North": p[0],
                    "East": p[1],
                    "Down": p[2],
                    "qx": q[0],
                    "qy": q[1],
                    "qz": q[2],
                    "qw": q[3],
                },
            }
            for ts, p, q in samples
        ]
        # json.dumps writes NaN as a bare literal, as a sloppy sender would.
        self.raw("telemetry", json.dumps({"ts": time.time(), "objects": objects}))

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


# The service reads the pages' watch marks every 0.25 s (pastview.runner's tick); this bound
# is forty reads, for a machine too loaded to tick on time.
WATCHED_WITHIN_S = 10.0


class GroupListener:
    """Receives what the service pushes to one drone's group."""

    def __init__(self, drone_id: str, service: ServiceThread | None) -> None:
        """`service`: the one in this process, waited on until it has seen the mark; None
        for another process's, whose caller sends until something comes through."""
        from channels.layers import get_channel_layer

        from pastview.service import group_name

        self.layer = get_channel_layer()
        self.drone_id = drone_id
        self.service = service
        self.group = group_name(drone_id)
        self.channel: str | None = None

    async def __aenter__(self) -> GroupListener:
        from pastview.runner import amark_watched
        from workers import outbox

        self.channel = await self.layer.new_channel()
        await self.layer.group_add(self.group, self.channel)
        # As a page's consumer does: the service pushes only for drones it has seen marked.
        await amark_watched(outbox.async_redis(), self.drone_id)
        deadline = time.monotonic() + WATCHED_WITHIN_S
        while self.service is not None and not self.service.watches(self.drone_id):
            assert time.monotonic() < deadline, "the past-view service never saw the watch mark"
            await asyncio.sleep(0.02)
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.layer.group_discard(self.group, self.channel)

    async def next(self, predicate=lambda m: True, timeout: float = 10.0) -> dict[str, Any]:  # type: ignore[no-untyped-def]
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError("no matching past-view message in time")
            try:
                event = await asyncio.wait_for(self.layer.receive(self.channel), left)
            except TimeoutError:
                raise AssertionError("no matching past-view message in time") from None
            message = event["message"]
            if predicate(message):
                return message


class ServiceThread:
    """``manage.py pastview``'s process object, run in a thread of the test."""

    def __init__(self, broker_url: str) -> None:
        from pastview.runner import PastViewProcess

        self.process = PastViewProcess(broker_url, client_id=f"pastview-test-{id(self)}")
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self.process.run, args=(self.stopping,), daemon=True)
        self.thread.start()
        assert self.process.subscribed.wait(10), "the past-view service did not subscribe"

    @property
    def service(self):  # type: ignore[no-untyped-def]
        return self.process.service

    def watches(self, drone_id: str) -> bool:
        """Whether the service now pushes the drone's updates (None: it pushes for all)."""
        watched = self.process.service.watched
        return watched is None or drone_id in watched

    def wait_until_watched(self, drone_id: str) -> None:
        """Until the service has read a page's watch mark: what it sends before is not pushed."""
        deadline = time.monotonic() + WATCHED_WITHIN_S
        while not self.watches(drone_id):
            assert time.monotonic() < deadline, "the past-view service never saw the watch mark"
            time.sleep(0.02)

    def stop(self) -> None:
        self.stopping.set()
        self.thread.join(10)


def close(a: list[float], b: list[float], tol: float = 1e-6) -> bool:
    return all(math.isclose(x, y, abs_tol=tol) for x, y in zip(a, b, strict=True))


def in_own_loop(test):  # type: ignore[no-untyped-def]
    """Run an async test on a fresh event loop in its own thread.

    The session's Playwright browser keeps an event loop running in the main thread once a
    browser test has run, and pytest-asyncio cannot start another there.
    """

    @functools.wraps(test)
    def run(*args, **kwargs):  # type: ignore[no-untyped-def]
        outcome: dict[str, Any] = {}

        def target() -> None:
            try:
                outcome["value"] = asyncio.run(test(*args, **kwargs))
            except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
                outcome["error"] = exc

        thread = threading.Thread(target=target, name=test.__name__)
        thread.start()
        thread.join()
        if "error" in outcome:
            raise outcome["error"]
        return outcome.get("value")

    return run

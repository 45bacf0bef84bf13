"""The media server as a real process, the agent's publisher as a real process, and a
WebRTC viewer (aiortc) that reads the capture time drawn into each frame."""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from django.conf import settings

from onboard import framecode
from onboard.live_video import PASSWORD_ENV, LiveVideoConfig
from runtime.processes import REPO_ROOT, Supervised, free_port, python_env


class MediaServer:
    """`manage.py mediaserver` on free ports, reading `database_name`."""

    def __init__(self, database_name: str, **env: str) -> None:
        self.port, self.drone_port = free_port(), free_port()
        self.before: Counter[str] = Counter()  # its counts when the current test began
        self.url = f"http://127.0.0.1:{self.port}"
        self.drone_url = f"http://127.0.0.1:{self.drone_port}"
        environment = python_env(
            DJANGO_SETTINGS_MODULE="config.settings.test",
            TEST_WORKER_DB_NAME=database_name,
            PYTHONUNBUFFERED="1",
            **env,
        )
        argv = [sys.executable, str(REPO_ROOT / "manage.py"), "mediaserver",
                "--port", str(self.port), "--drone-port", str(self.drone_port)]  # fmt: skip
        log = Path(settings.TEST_DATA_DIR) / f"mediaserver-{self.port}.log"
        self.process = Supervised(
            "media server",
            argv,
            environment,
            log,
            ready_text=("media server ready",),
            port=self.port,
        )
        self.process.start().wait_ready(30)

    def get(self, path: str) -> dict:
        with urllib.request.urlopen(self.url + path, timeout=5) as response:
            return json.loads(response.read())

    def stop(self) -> None:
        self.process.stop(10)


class Publisher:
    """`python -m onboard.live_video` as the agent runs it, its pose pipe held open."""

    def __init__(self, config: LiveVideoConfig) -> None:
        env = python_env(**{PASSWORD_ENV: config.password})
        self.process = subprocess.Popen(
            config.argv(), stdin=subprocess.PIPE, env=env, cwd=str(REPO_ROOT)
        )

    def stop(self) -> None:
        if self.process.stdin:
            self.process.stdin.close()
        self.process.terminate()
        self.process.wait(10)


def post(url: str, body: bytes, headers: dict[str, str]) -> tuple[int, bytes]:
    request = urllib.request.Request(url, data=body, method="POST", headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=15) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def wait_until(predicate, timeout: float, interval: float = 0.2):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    raise AssertionError(f"not within {timeout} s")


@dataclass
class Watched:
    status: int
    detail: bytes
    captured_ms: list[int]
    sizes: list[tuple[int, int]]


async def _watch(url: str, headers: dict[str, str], frames: int, timeout: float) -> Watched:
    from aiortc import RTCPeerConnection, RTCSessionDescription

    pc = RTCPeerConnection()
    pc.addTransceiver("video", direction="recvonly")
    got: asyncio.Queue = asyncio.Queue()
    pc.on("track", lambda track: got.put_nowait(track))
    await pc.setLocalDescription(await pc.createOffer())
    loop = asyncio.get_running_loop()
    status, body = await loop.run_in_executor(
        None, post, url, pc.localDescription.sdp.encode(),
        {"Content-Type": "application/sdp", **headers},
    )  # fmt: skip
    captured: list[int] = []
    sizes: list[tuple[int, int]] = []
    try:
        if status != 201:
            return Watched(status, body, captured, sizes)
        await pc.setRemoteDescription(RTCSessionDescription(sdp=body.decode(), type="answer"))
        track = await asyncio.wait_for(got.get(), timeout)
        deadline = loop.time() + timeout
        while len(captured) < frames:
            frame = await asyncio.wait_for(track.recv(), max(0.1, deadline - loop.time()))
            ms = framecode.read(frame.to_ndarray(format="gray"))
            if ms is not None:
                captured.append(ms)
                sizes.append((frame.width, frame.height))
        return Watched(status, body, captured, sizes)
    finally:
        await pc.close()


def watch(url: str, headers: dict[str, str], frames: int = 10, timeout: float = 20.0) -> Watched:
    """Watch a WHEP endpoint until `frames` frames with a readable capture time arrive."""
    return asyncio.run(_watch(url, headers, frames, timeout))


def ticket_for(drone_id: str, organisation_id: int, ttl_s: float = 60.0) -> str:
    from livevideo import access, tickets

    return tickets.mint(access.ticket_key(), drone_id, organisation_id, ttl_s)


def assert_in_step(captured: list[float], cursor: float, frame_s: float) -> None:
    """The frame shown at `cursor` (its capture time `frame_s`, read from its pixels) is one
    of the recorded frames `captured` (Unix seconds), and the last one captured at or before
    the cursor or (a seek lands on a frame by the ground's receive times) its neighbour."""
    due = max(i for i, c in enumerate(captured) if c <= cursor + 0.001)
    shown = min(range(len(captured)), key=lambda i: abs(captured[i] - frame_s))
    assert abs(captured[shown] - frame_s) < 0.002, (frame_s, captured)
    assert abs(shown - due) <= 1, (cursor, frame_s, captured[due])


__all__ = ["MediaServer", "Publisher", "os"]

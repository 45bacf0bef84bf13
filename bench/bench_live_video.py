"""Live video: glass-to-glass delay and CPU per stream (docs/video.md).

Each simulated camera (the agent's own publisher process, onboard/live_video.py) sends
VP8 over WebRTC to the relay (livevideo.relay and its HTTP apps, in a process of their
own), and a WebRTC viewer in this process decodes every frame and reads the capture time
drawn into it: the delay from capture to a decoded frame at the viewer, through the
drone's encoder, the relay's decode and re-encode, and two WebRTC hops on loopback.

Baseline, in the same run: the same synthetic frames, stamped the same way, sent raw
(uncompressed RGB, split into datagrams) over a UDP socket on loopback and read back, so
the ratio is what WebRTC and the codec cost over the bare transport.

CPU per stream: the relay's and the publishers' process CPU time over the run divided by
the number of streams (the relay recording each stream as the media server does),
against the CPU the raw UDP sender and receiver take per stream.

Streams one machine holds: the same path with 1, 2, 4, 6, ... streams at once (the
publishers, the relay and the viewer all on this machine) until a step misses the goal
for a held stream: p95 glass-to-glass under 400 ms and at least 90 % of the frames sent
arriving. Baseline, in the same run: the raw UDP path stepped the same way to the same
goal. The relay's own CPU per stream also gives the streams a ground that hosts no
drones would hold (its cores at 80 % over that figure), printed beside.

Run: .venv/bin/python -m bench.bench_live_video
"""

from __future__ import annotations

import asyncio
import json
import os
import secrets
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import psutil

from bench.common import median, percentile, record

STREAMS = 2
FPS = 15
SECONDS = 10.0
WIDTH, HEIGHT = 320, 240
DATAGRAM = 60_000
GOAL_P95_MS = 400.0
GOAL = f"p95 glass-to-glass < {GOAL_P95_MS:.0f} ms on loopback"


# -- the relay process ---------------------------------------------------------------------


def run_relay(port: int, drone_port: int) -> None:
    """The media server's relay and HTTP apps; publishers are the drones named in
    BENCH_DRONES (id:password,...), all of one organisation."""
    import uvicorn

    from livevideo.recording import Recorder
    from livevideo.relay import Relay
    from livevideo.server import SharedLoopServer, drone_app, ground_app
    from workers.broker.credentials import check_password, hash_password

    hashes = dict(pair.split(":", 1) for pair in os.environ["BENCH_DRONES"].split(","))
    hashes = {drone: hash_password(password) for drone, password in hashes.items()}

    async def authenticate(drone_id: str, password: str) -> int | None:
        stored = hashes.get(drone_id)
        return 1 if stored and check_password(password, stored) else None

    async def serve() -> None:
        # Recording as the media server does by default (its CPU counts per stream).
        recordings = Path(tempfile.mkdtemp(prefix="bench-video-"))
        relay = Relay(recorder=lambda drone: Recorder(recordings / f"{drone}.webm", 1 << 30))
        key = os.environ["BENCH_TICKET_KEY"].encode()
        servers = [
            SharedLoopServer(uvicorn.Config(ground_app(relay, key), port=port, log_level="warning")),
            SharedLoopServer(uvicorn.Config(drone_app(relay, authenticate), port=drone_port,
                                   log_level="warning")),
        ]  # fmt: skip
        await asyncio.gather(*(s.serve() for s in servers))

    asyncio.run(serve())


# -- the WebRTC path ----------------------------------------------------------------------


RAMP = (1, 2, 4, 6, 8, 12, 16)
HELD_SHARE = 0.9  # a held stream delivers at least this share of the frames sent
USABLE_CPU = 0.8  # share of a ground's cores the projection counts on


@dataclass
class Measured:
    delays_ms: list[float]
    cpu_s_per_stream: float
    frames_per_stream: float = 0.0
    relay_cpu_s_per_stream: float = 0.0

    def held(self) -> bool:
        sent = FPS * SECONDS
        return bool(self.delays_ms) and percentile(self.delays_ms, 95) < GOAL_P95_MS \
            and self.frames_per_stream >= HELD_SHARE * sent  # fmt: skip


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_port(port: int, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return
        except OSError:
            time.sleep(0.1)
    raise RuntimeError(f"nothing on port {port}")


def _wait_live(url: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with urllib.request.urlopen(url, timeout=5) as response:
            if json.loads(response.read()).get("frames", 0) > FPS:
                return
        time.sleep(0.2)
    raise RuntimeError(f"{url} did not go live")


async def _view(url: str, ticket: str, seconds: float, delays: list[float]) -> None:
    from aiortc import RTCPeerConnection, RTCSessionDescription

    from onboard import framecode

    pc = RTCPeerConnection()
    pc.addTransceiver("video", direction="recvonly")
    tracks: asyncio.Queue = asyncio.Queue()
    pc.on("track", tracks.put_nowait)
    await pc.setLocalDescription(await pc.createOffer())
    loop = asyncio.get_running_loop()
    status, body = await loop.run_in_executor(
        None, post, url, pc.localDescription.sdp.encode(),
        {"Content-Type": "application/sdp", "Authorization": f"Bearer {ticket}"},
    )  # fmt: skip
    assert status == 201, (status, body)
    await pc.setRemoteDescription(RTCSessionDescription(sdp=body.decode(), type="answer"))
    track = await asyncio.wait_for(tracks.get(), 20)
    await asyncio.wait_for(track.recv(), 20)  # counted from the first frame (a keyframe)
    end = loop.time() + seconds
    while loop.time() < end:
        frame = await asyncio.wait_for(track.recv(), 10)
        captured = framecode.read(frame.to_ndarray(format="gray"))
        if captured is not None:
            delays.append(time.time() * 1000 - captured)
    await pc.close()


def post(url: str, body: bytes, headers: dict[str, str]) -> tuple[int, bytes]:
    request = urllib.request.Request(url, data=body, method="POST", headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=15) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def _start_publishers(drones: dict[str, str], drone_port: int) -> list[subprocess.Popen]:
    from onboard.live_video import PASSWORD_ENV, LiveVideoConfig
    from runtime.processes import python_env

    publishers = []
    for drone_id, password in drones.items():
        config = LiveVideoConfig(f"http://127.0.0.1:{drone_port}", drone_id, password,
                                 WIDTH, HEIGHT, FPS)  # fmt: skip
        publishers.append(
            subprocess.Popen(config.argv(), stdin=subprocess.PIPE,
                             env=python_env(**{PASSWORD_ENV: password}))
        )  # fmt: skip
    return publishers


def _cpu_s(processes: list[psutil.Process]) -> float:
    return sum(sum(p.cpu_times()[:2]) for p in processes)


def webrtc_path(streams: int = STREAMS) -> Measured:
    from livevideo import tickets
    from runtime.processes import python_env

    drones = {f"BENCH_{n}": secrets.token_hex(8) for n in range(streams)}
    key = secrets.token_hex(16)
    port, drone_port = _free_port(), _free_port()
    env = python_env(
        BENCH_DRONES=",".join(f"{d}:{p}" for d, p in drones.items()), BENCH_TICKET_KEY=key
    )
    relay = subprocess.Popen(
        [sys.executable, "-m", "bench.bench_live_video", "relay", str(port), str(drone_port)],
        env=env,
    )
    publishers: list[subprocess.Popen] = []
    try:
        _wait_port(port)
        _wait_port(drone_port)
        publishers = _start_publishers(drones, drone_port)
        for drone in drones:  # connected and past the first key frames
            _wait_live(f"http://127.0.0.1:{port}/streams/{drone}")
        relay_ps = [psutil.Process(relay.pid)]
        watched = relay_ps + [psutil.Process(p.pid) for p in publishers]
        before, relay_before = _cpu_s(watched), _cpu_s(relay_ps)
        delays: list[float] = []

        async def view_all() -> None:
            await asyncio.gather(*(
                _view(f"http://127.0.0.1:{port}/whep/{drone}",
                      tickets.mint(key.encode(), drone, 1, 60), SECONDS, delays)
                for drone in drones
            ))  # fmt: skip

        asyncio.run(view_all())
        per_stream = streams * SECONDS
        return Measured(delays, (_cpu_s(watched) - before) / per_stream, len(delays) / streams,
                        (_cpu_s(relay_ps) - relay_before) / per_stream)  # fmt: skip
    finally:
        for process in (*publishers, relay):
            process.terminate()
            process.wait(10)


# -- the raw UDP baseline ------------------------------------------------------------------


def udp_path(streams: int = STREAMS) -> Measured:
    from onboard import framecode
    from onboard.synthetic_camera import render_view_rgb

    delays: list[float] = []
    stop = threading.Event()
    receivers = []
    cpu_start = time.process_time()

    def receive(sock: socket.socket) -> None:
        size = WIDTH * HEIGHT * 3
        buffer = bytearray()
        sock.settimeout(0.5)
        while not stop.is_set():
            try:
                chunk = sock.recv(65536)
            except TimeoutError:
                continue
            if chunk[:1] == b"\x01":  # the first datagram of a frame
                buffer = bytearray()
            buffer += chunk[1:]
            if len(buffer) == size:
                rgb = np.frombuffer(bytes(buffer), np.uint8).reshape(HEIGHT, WIDTH, 3)
                luma = rgb[:, :, 1]
                captured = framecode.read(luma)
                if captured is not None:
                    delays.append(time.time() * 1000 - captured)

    def send(sock: socket.socket, address: tuple[str, int], n: int) -> None:
        period = 1.0 / FPS
        next_at = time.monotonic()
        end = next_at + SECONDS
        while time.monotonic() < end:
            rgb = render_view_rgb((n * 5.0, time.monotonic() % 50, -20.0), (0, 0, 0, 1),
                                  width=WIDTH, height=HEIGHT).copy()  # fmt: skip
            framecode.stamp(rgb, int(time.time() * 1000))
            data = rgb.tobytes()
            for offset in range(0, len(data), DATAGRAM):
                marker = b"\x01" if offset == 0 else b"\x00"
                sock.sendto(marker + data[offset : offset + DATAGRAM], address)
            next_at += period
            time.sleep(max(0.0, next_at - time.monotonic()))

    threads = []
    for n in range(streams):
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
        rx.bind(("127.0.0.1", 0))
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        receivers.append(rx)
        threads.append(threading.Thread(target=receive, args=(rx,), daemon=True))
        threads.append(threading.Thread(target=send, args=(tx, rx.getsockname(), n)))
    for thread in threads:
        thread.start()
    for thread in threads[1::2]:
        thread.join()
    stop.set()
    cpu = time.process_time() - cpu_start
    return Measured(delays, cpu / streams / SECONDS, len(delays) / streams)


def held_streams(path: Callable[[int], Measured]) -> tuple[int, Measured | None]:
    """The most streams `path` carried to the goal in the ramp, and its measure there."""
    held, measured = 0, None
    for streams in RAMP:
        try:
            step = path(streams)
        except (RuntimeError, TimeoutError, AssertionError) as exc:
            print(f"  {streams} streams: failed ({exc!r})", flush=True)
            break
        p95 = percentile(step.delays_ms, 95) if step.delays_ms else float("nan")
        print(f"  {streams} streams: p95 {p95:.0f} ms, {step.frames_per_stream:.0f} frames "
              f"per stream of {FPS * SECONDS:.0f}", flush=True)  # fmt: skip
        if not step.held():
            break
        held, measured = streams, step
    return held, measured


def record_streams_held() -> None:
    print("raw UDP ramp:", flush=True)
    raw_held, _ = held_streams(udp_path)
    print("WebRTC ramp:", flush=True)
    held, measured = held_streams(webrtc_path)
    relay_cpu = measured.relay_cpu_s_per_stream if measured else 0.0
    cores = psutil.cpu_count() or 1
    record(
        "live_video.streams_held",
        value=held,
        unit="streams",
        baseline_name="raw RGB frames over UDP sockets, same ramp and goal",
        baseline_value=raw_held,
        higher_is_better=True,
        goal=f"{WIDTH}x{HEIGHT} {FPS} fps streams, each p95 < {GOAL_P95_MS:.0f} ms and "
        f"{HELD_SHARE:.0%} of its frames, drones and ground on one machine",
        cores=cores,
        relay_cpu_per_stream_pct=round(relay_cpu * 100, 1),
        ground_only_projection=int(cores * USABLE_CPU / relay_cpu) if relay_cpu else None,
    )


def main() -> None:
    raw = udp_path()
    rtc = webrtc_path()
    assert rtc.delays_ms and raw.delays_ms, "no frames measured"
    for name, q in (("p50", 50), ("p95", 95)):
        record(
            f"live_video.glass_to_glass_{name}_ms",
            value=round(percentile(rtc.delays_ms, q), 1),
            unit="ms",
            baseline_name=f"raw RGB frames over a UDP socket, {name}",
            baseline_value=round(max(percentile(raw.delays_ms, q), 0.1), 2),
            higher_is_better=False,
            goal=GOAL,
            streams=STREAMS,
            fps=FPS,
            size=f"{WIDTH}x{HEIGHT}",
            frames=len(rtc.delays_ms),
        )
    record(
        "live_video.cpu_per_stream",
        value=round(rtc.cpu_s_per_stream * 100, 1),
        unit="% of a core",
        baseline_name="raw UDP sender and receiver",
        baseline_value=round(raw.cpu_s_per_stream * 100, 1),
        higher_is_better=False,
        goal="under 50 % of a core per 320x240 15 fps stream",
        median_delay_ms=round(median(rtc.delays_ms), 1),
    )
    record_streams_held()


if __name__ == "__main__":
    if sys.argv[1:2] == ["relay"]:
        run_relay(int(sys.argv[2]), int(sys.argv[3]))
    else:
        main()

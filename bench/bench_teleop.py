"""Teleoperation latency: a stick move on the past-view page → the flight controller's setpoint.

    .venv/bin/python -m bench.bench_teleop

Runs against the test profile's services (`scripts/services.sh start test`) like
bench_ground: its own database and Redis database, a private Mosquitto, and the real
ground as subprocesses (the ASGI app under uvicorn, the gateway, the past-view service).
N drones (10) are the real thing: the flight-controller simulator and the onboard agent
each (firmware.sim.fleet), flying, with their camera and pose streams on so the page has
the fresh view teleoperation needs.

One operator page per drone (a websocket each, all at once) sends a stick move
(`{"type": "teleop", "forward": ±1}`) and waits for its answer, no faster than the rate
limit (PASTVIEW_TELEOP_HZ). A move's latency runs from the websocket send to the moment
the drone's simulator applies the move's last setpoint (the simulator logs each setpoint
with the wall clock). Baseline, same run, same drones, measured the same way: the bare
MQTT hop, a ground client publishing the same command to `<id>/control/in` itself.

Keys: pastview.teleop_latency_p50, pastview.teleop_latency_p99 (goals 20 ms and 50 ms).
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from bench import private_ground
from bench.common import test_profile_env
from runtime.processes import Supervised, wait_for
from workers.ground import gateway_argv, pastview_argv

DB_NAME = "bench_teleop"
REDIS_DB = 12
DRONES = int(os.environ.get("BENCH_TELEOP_DRONES", 10))
MOVES = int(os.environ.get("BENCH_TELEOP_MOVES", 30))  # per drone: 300 moves, a p99 of three
HOME = (38.736946, -9.142685, 100.0)
SCALE = 2.0
ALTITUDE_M = 10.0
AGENT_ARGS = ["--video-rate", "2", "--pose-rate", "10"]
SETPOINT = re.compile(rb"setpoint \S+ \S+ \S+ \S+ at (\d+\.\d+)")
# A move's setpoints are applied before the drone answers; a line may reach the log a
# moment after the answer reaches the page.
LOG_SLACK_S = 0.5


def setup_django() -> None:
    os.environ["DJANGO_SETTINGS_MODULE"] = "config.settings.test"
    os.environ["TEST_DB_NAME"] = f"test_{DB_NAME}"
    parts = urlsplit(test_profile_env()["REDIS_URL"])
    os.environ["REDIS_URL"] = urlunsplit(parts._replace(path=f"/{REDIS_DB}"))
    import django

    django.setup()


class SetpointLog:
    """The setpoint lines one simulator logged, read on from where the last read ended."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0

    def skip(self) -> None:
        self.offset = self.path.stat().st_size if self.path.exists() else 0

    def stamps(self) -> list[float]:
        with open(self.path, "rb") as f:
            f.seek(self.offset)
            data = f.read()
        end = data.rfind(b"\n") + 1  # a line still being written is read next time
        self.offset += end
        return [float(m.group(1)) for m in SETPOINT.finditer(data[:end])]

    def last_after(self, start: float) -> float | None:
        """The last setpoint applied since `start` (waiting a moment for the log)."""
        deadline = time.monotonic() + LOG_SLACK_S
        found = [t for t in self.stamps() if t >= start]
        while not found and time.monotonic() < deadline:
            time.sleep(0.01)
            found = [t for t in self.stamps() if t >= start]
        return max(found) if found else None


@dataclass
class Bench:
    broker: Any
    db_name: str
    token: str
    session: str
    names: list[str]
    passwords: dict[str, str]
    folder: Path
    processes: list[Supervised] = field(default_factory=list)
    drones: list[Any] = field(default_factory=list)
    base_url: str = ""


def _set_up() -> Bench:
    folder = Path(tempfile.mkdtemp(prefix="bench-teleop-"))
    db_name, broker = private_ground.database_and_broker(folder, "bench-ground")
    token, session, names, passwords = _provision()
    return Bench(broker, db_name, token, session, names, passwords, folder)


def _provision() -> tuple[str, str, list[str], dict[str, str]]:
    """An operator (API token and a signed-in session) and the drones' broker passwords."""
    from django.conf import settings
    from django.test import Client

    names = [f"BENCH_T{i:02d}" for i in range(DRONES)]
    user, token, passwords = private_ground.operator_and_drones(names)
    client = Client()
    client.force_login(user)
    return token, client.cookies[settings.SESSION_COOKIE_NAME].value, names, passwords


def _start_ground(bench: Bench) -> None:
    env = private_ground.ground_env(bench.db_name, bench.broker)
    for name, argv in (("gateway", gateway_argv()), ("pastview", pastview_argv())):
        bench.processes.append(Supervised(name, argv, env).start())
    web = private_ground.start_web(env, 60)
    bench.processes.append(web)
    bench.base_url = web.url


def _start_drones(bench: Bench) -> None:
    from firmware.sim.fleet import start_drone

    for i, name in enumerate(bench.names):
        home = (HOME[0] + 0.0005 * i, HOME[1], HOME[2])
        url = f"mqtt://{name}:{bench.passwords[name]}@127.0.0.1:{bench.broker.port}"
        bench.drones.append(
            start_drone(
                bench.folder / name,
                name,
                url,
                home,
                time_scale=SCALE,
                agent_args=AGENT_ARGS,
            )
        )


def _command(bench: Bench, name: str, command: str, **params: object) -> dict:
    import requests

    response = requests.post(
        f"{bench.base_url}/api/v1/drones/{name}/commands/",
        json={"command": command, "params": params},
        headers={"Authorization": f"Token {bench.token}"},
        timeout=30,
    )
    return {"status": response.status_code, **response.json()}


def _until_ok(bench: Bench, name: str, command: str, **params: object) -> None:
    """Send until the drone accepts (an agent may still be connecting its controller)."""
    answer: dict = {}

    def sent() -> bool:
        answer.update(_command(bench, name, command, **params))
        return bool(answer.get("ok"))

    if not wait_for(sent, 60, interval=1.0):
        raise RuntimeError(f"{name}: {command} failed: {answer}")


def _take_off(bench: Bench) -> None:
    """Every drone online, armed and at altitude."""
    from fleet.models import Drone

    def online() -> bool:
        return Drone.objects.filter(drone_id__in=bench.names, online=True).count() == DRONES

    if not wait_for(online, 120, interval=0.5):
        raise RuntimeError("the drones did not come online")
    for name in bench.names:
        _until_ok(bench, name, "arm")
        _until_ok(bench, name, "takeoff", altitude=ALTITUDE_M)

    def airborne() -> bool:
        up = Drone.objects.filter(drone_id__in=bench.names, airborne=True, alt__gt=ALTITUDE_M - 1)
        return up.count() == DRONES

    if not wait_for(airborne, 120, interval=0.5):
        raise RuntimeError("the drones did not reach altitude")


# -- through the page ------------------------------------------------------------------------


async def _page_moves(bench: Bench, name: str, log: SetpointLog) -> tuple[list[float], list[str]]:
    """One operator page: wait for a fresh, tracked view, then send MOVES moves."""
    from django.conf import settings
    from websockets.asyncio.client import connect

    host = urlsplit(bench.base_url).netloc
    headers = {"Cookie": f"{settings.SESSION_COOKIE_NAME}={bench.session}"}
    interval = 1.0 / settings.PASTVIEW_TELEOP_HZ
    latencies: list[float] = []
    errors: list[str] = []
    async with connect(
        f"ws://{host}/ws/pastview/{name}/",
        additional_headers=headers,
        origin=f"http://{host}",  # type: ignore[arg-type]
        max_size=None,
        ping_interval=None,  # a busy machine must not end the page: the moves tell
    ) as page:
        await _until_fresh(page)
        for i in range(MOVES):
            log.skip()
            began = time.time()
            forward = 1 if i % 2 == 0 else -1  # back and forth: the drone stays near home
            await page.send(json.dumps({"type": "teleop", "forward": forward}))
            answer = await _answer(page)
            answered = time.time()
            if not answer["ok"]:
                errors.append(answer["error"])
            else:
                applied = await asyncio.to_thread(log.last_after, began)
                if applied is None:
                    errors.append("no setpoint logged")
                else:
                    latencies.append((applied - began) * 1000)
            # The next move goes when the rate limit admits it at once: a full interval
            # after this one ended (the limiter counts from when a move started), so what
            # is measured is the path, not the limiter's wait.
            resume = max(began + interval * 1.2, answered + interval)
            await asyncio.sleep(max(0.0, resume - time.time()))
    return latencies, errors


async def _until_fresh(page: Any, timeout: float = 60.0) -> None:
    """Until the page has had a camera frame and a tracked pose (what teleop needs)."""
    live = tracked = False
    deadline = time.monotonic() + timeout
    while not (live and tracked):
        message = json.loads(await asyncio.wait_for(page.recv(), deadline - time.monotonic()))
        kind = message.get("type")
        live = live or kind == "live"
        tracked = tracked or (
            kind == "update" and message.get("tracking") == "tracked" and bool(message.get("frame"))
        )


async def _answer(page: Any) -> dict:
    while True:
        message = json.loads(await asyncio.wait_for(page.recv(), 30))
        if message.get("type") == "teleop":
            return message


async def _through_pages(bench: Bench, logs: dict[str, SetpointLog]) -> tuple[list, list]:
    results = await asyncio.gather(*(_page_moves(bench, n, logs[n]) for n in bench.names))
    return [x for r in results for x in r[0]], [x for r in results for x in r[1]]


# -- the bare MQTT hop ---------------------------------------------------------------------


def _bare_moves(bench: Bench, logs: dict[str, SetpointLog]) -> list[float]:
    """The same moves published by a ground client of our own, all drones at once."""
    from bench.bench_ground import _client
    from onboard import protocol

    ground = _client("ground", "bench-ground", bench.broker.port, "bench-teleop-bare")
    answered: dict[str, threading.Event] = {}
    ground.on_message = lambda c, u, m: answered.get(
        json.loads(m.payload).get("request_id"), threading.Event()
    ).set()
    subscribed = threading.Event()
    ground.on_subscribe = lambda *args: subscribed.set()
    ground.subscribe("+/control/out", qos=1)
    subscribed.wait(5)
    latencies: list[float] = []

    def moves(name: str) -> None:
        for i in range(MOVES):
            request = protocol.control_request("changeN", {"value": 0.5 if i % 2 == 0 else -0.5})
            answered[request.request_id] = event = threading.Event()
            logs[name].skip()
            began = time.time()
            ground.publish(f"{name}/control/in", json.dumps(request.to_dict()), qos=1)
            if event.wait(10):
                applied = logs[name].last_after(began)
                if applied is not None:
                    latencies.append((applied - began) * 1000)
            time.sleep(0.3)

    threads = [threading.Thread(target=moves, args=(n,)) for n in bench.names]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    ground.disconnect()
    ground.loop_stop()
    return latencies


def _record(teleop: list[float], bare: list[float], errors: list[str]) -> None:
    from bench.common import percentile, record

    extra = {"drones": DRONES, "moves": len(teleop), "refused": len(errors)}
    extra["load_average"] = [round(x, 2) for x in os.getloadavg()]
    for key, q, goal in (
        ("pastview.teleop_latency_p50", 50, "p50 under 20 ms with 10 drones flying"),
        ("pastview.teleop_latency_p99", 99, "p99 under 50 ms with 10 drones flying"),
    ):
        record(
            key,
            value=percentile(teleop, q),
            unit="ms",
            baseline_name=f"bare MQTT hop (ground client → agent → simulator) p{q}, same drones",
            baseline_value=percentile(bare, q),
            higher_is_better=False,
            goal=goal,
            **extra,
        )


def _tear_down(bench: Bench) -> None:
    from django.db import connection

    for drone in bench.drones:
        drone.stop()
    for process in bench.processes:
        process.stop(10)
    bench.broker.stop()
    connection.creation.destroy_test_db(bench.db_name, verbosity=0)


def main() -> None:
    setup_django()
    bench = _set_up()
    try:
        _start_ground(bench)
        _start_drones(bench)
        _take_off(bench)
        logs = {d.drone_id: SetpointLog(d.folder / "sim.log") for d in bench.drones}
        teleop, errors = asyncio.run(_through_pages(bench, logs))
        bare = _bare_moves(bench, logs)
        if not teleop or not bare:
            raise RuntimeError(f"no moves measured; refusals: {errors[:5]}")
        _record(teleop, bare, errors)
        summary = {
            "teleop_p50": statistics.median(teleop),
            "bare_p50": statistics.median(bare),
            "refusals": errors[:5],
            "load_average": os.getloadavg(),
        }
        print(json.dumps(summary, indent=1))
    finally:
        _tear_down(bench)


if __name__ == "__main__":
    main()

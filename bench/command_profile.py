"""Where one command's round trip goes: each step's wall and CPU time, its queries, its
trips to a thread.

    .venv/bin/python -m bench.command_profile [--command arm] [--samples 300] [--cprofile F]

Not a figure of bench/results.json (`bench.bench_ground` measures the round trip over
HTTP): this takes the same ground apart. It sets up what `bench.bench_ground` does (a
test database, a private Mosquitto, the real gateway as a subprocess, 100 responders
answering at once) and calls the real ASGI application (`config.asgi.application`, every
middleware) in this process, so that it can time the named steps of
`POST /api/v1/drones/{id}/commands/` from the inside: `time.perf_counter` for the wall
time, `time.thread_time` for the CPU time of the steps that run in one thread. Every SQL
statement of one command is printed, and each trip from the event loop to a thread, by
the function it carries. `--cprofile F` writes a cProfile of the request threads' work
(the event loop's is printed) to F.

The responders run in this process (paho threads): the CPU times are the thread's own,
unaffected; the wall times share the machine as the HTTP figure does.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import cProfile
import functools
import inspect
import json
import os
import statistics
import threading
import time
from collections.abc import Callable
from typing import Any

from bench import bench_ground, private_ground
from runtime.processes import Supervised
from workers.ground import gateway_argv

# (module, attribute path, label): the steps of a command, outermost first.
STEPS = (
    ("fleet.async_views", "AsyncAPIView.adispatch", "view (all but the HTTP server)"),
    ("fleet.api", "DroneCommandView._prepare", "  checks in the request thread"),
    ("rest_framework.views", "APIView.perform_authentication", "    token authentication"),
    (
        "django.db.backends.base.base",
        "BaseDatabaseWrapper.connect",
        "      its connection from the pool (checked)",
    ),
    ("rest_framework.views", "APIView.check_permissions", "    permission classes"),
    ("config.throttling", "TogetherThrottles.check_throttles", "    throttles (command rate)"),
    ("fleet.api", "CommandRequestSerializer.is_valid", "    request serializer"),
    ("fleet.commands", "find_drone", "    drone, organisation and role"),
    ("fleet.airworthiness", "refused", "    airworthiness (arm)"),
    ("checklists.gate", "refusal", "    pre-flight checklist (arm, takeoff)"),
    ("fleet.envelopes", "check_command", "    flight envelope"),
    ("workers.direct", "arequest", "  publish, drone's reply (direct link)"),
    ("fleet.commands", "record", "  command log and audit (after the answer)"),
)


class Recorder:
    """What the wrapped steps, statements and thread trips report while `on`."""

    def __init__(self) -> None:
        self.on = False
        self.wall: dict[str, list[float]] = collections.defaultdict(list)
        self.cpu: dict[str, list[float]] = collections.defaultdict(list)
        self.statements: list[tuple[str, str]] = []
        self.hops: collections.Counter[str] = collections.Counter()
        self.profile: cProfile.Profile | None = None

    def timed(self, step: Callable, label: str) -> Callable:
        if inspect.iscoroutinefunction(step):

            @functools.wraps(step)
            async def wrapped_async(*args: Any, **kwargs: Any) -> Any:
                began = time.perf_counter()
                try:
                    return await step(*args, **kwargs)
                finally:
                    if self.on:
                        self.wall[label].append((time.perf_counter() - began) * 1000)

            return wrapped_async

        @functools.wraps(step)
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            began, cpu = time.perf_counter(), time.thread_time()
            try:
                return step(*args, **kwargs)
            finally:
                if self.on:
                    self.wall[label].append((time.perf_counter() - began) * 1000)
                    self.cpu[label].append((time.thread_time() - cpu) * 1000)

        return wrapped


def instrument(recorder: Recorder) -> None:
    """Wrap each step of STEPS, the database cursor and asgiref's trips to a thread."""
    import importlib

    from asgiref.sync import SyncToAsync
    from django.db.backends import utils

    for module_name, path, label in STEPS:
        owner: Any = importlib.import_module(module_name)
        *parents, name = path.split(".")
        for parent in parents:
            owner = getattr(owner, parent)
        setattr(owner, name, recorder.timed(getattr(owner, name), label))

    execute = utils.CursorWrapper._execute

    def recorded_execute(cursor: Any, sql: str, *args: Any) -> Any:
        if recorder.on:
            recorder.statements.append((threading.current_thread().name, sql))
        return execute(cursor, sql, *args)

    utils.CursorWrapper._execute = recorded_execute
    _instrument_hops(recorder, SyncToAsync)


def _instrument_hops(recorder: Recorder, sync_to_async: Any) -> None:
    call, handler = sync_to_async.__call__, sync_to_async.thread_handler

    async def counted_call(self: Any, *args: Any, **kwargs: Any) -> Any:
        if recorder.on:
            recorder.hops[getattr(self.func, "__qualname__", repr(self.func))] += 1
        return await call(self, *args, **kwargs)

    def profiled_handler(self: Any, *args: Any, **kwargs: Any) -> Any:
        if not (recorder.on and recorder.profile):
            return handler(self, *args, **kwargs)
        recorder.profile.enable()  # one request at a time: one thread at a time
        try:
            return handler(self, *args, **kwargs)
        finally:
            recorder.profile.disable()

    sync_to_async.__call__ = counted_call
    sync_to_async.thread_handler = profiled_handler


async def post(app: Any, path: str, body: bytes, token: str) -> tuple[int, bytes]:
    """One request through the ASGI application, as uvicorn hands it over."""
    headers = [
        (b"host", b"127.0.0.1"),
        (b"authorization", f"Token {token}".encode()),
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
    ]
    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": "POST",
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "query_string": b"",
        "root_path": "",
        "server": ("127.0.0.1", 80),
        "client": ("127.0.0.1", 50000),
        "headers": headers,
    }
    messages = [{"type": "http.request", "body": body, "more_body": False}]
    answer: dict[str, Any] = {"status": 0, "body": b""}

    async def receive() -> dict:
        if messages:
            return messages.pop()
        await asyncio.Event().wait()  # the client stays connected
        return {}

    async def send(message: dict) -> None:
        if message["type"] == "http.response.start":
            answer["status"] = message["status"]
        elif message["type"] == "http.response.body":
            answer["body"] += message.get("body", b"")

    await app(scope, receive, send)
    return answer["status"], answer["body"]


async def commands(
    recorder: Recorder, names: list[str], token: str, command: str, samples: int
) -> list[float]:
    """`samples` round trips, after 40 unrecorded ones (the direct link, connections)."""
    from config.asgi import application

    body = json.dumps({"command": command, "params": {}}).encode()
    times = []
    for i in range(samples + 40):
        recorder.on = i >= 40
        began = time.perf_counter()
        status, content = await post(
            application, f"/api/v1/drones/{names[i % len(names)]}/commands/", body, token
        )
        if recorder.on:
            times.append((time.perf_counter() - began) * 1000)
        if status != 200 or not json.loads(content)["ok"]:
            raise RuntimeError(f"{status} {content[:300]!r}")
    recorder.on = False
    return times


def report(recorder: Recorder, times: list[float], bare: list[float], samples: int) -> None:
    def p(values: list[float], q: float) -> float:
        return sorted(values)[min(len(values) - 1, int(len(values) * q))]

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"round trip (ASGI app) p50 {statistics.median(times):6.2f} ms  p99 {p(times, 0.99):.2f}")
    print(f"bare MQTT baseline    p50 {statistics.median(bare):6.2f} ms  p99 {p(bare, 0.99):.2f}")
    print(f"{'step':48s} {'wall p50':>9s} {'cpu p50':>9s}   (ms)")
    for _, _, label in STEPS:
        if recorder.wall.get(label):
            cpu = recorder.cpu.get(label)
            shown = f"{statistics.median(cpu):9.2f}" if cpu else f"{'':9s}"
            print(f"{label:48s} {statistics.median(recorder.wall[label]):9.2f} {shown}")
    print("trips to a thread per command:")
    for name, count in recorder.hops.most_common():
        print(f"  {count / samples:4.1f}  {name}")
    print(f"SQL statements per command: {len(recorder.statements) / samples:.1f}; one command's:")
    per = len(recorder.statements) // samples
    for thread, sql in recorder.statements[-per:]:
        print(f"  [{thread}] {sql[:160]}{'…' if len(sql) > 160 else ''}")


def new_loop() -> asyncio.AbstractEventLoop:
    """uvloop's, as uvicorn runs the application, when it is installed."""
    try:
        import uvloop
    except ImportError:
        return asyncio.new_event_loop()
    return uvloop.new_event_loop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--command", default="arm")
    parser.add_argument("--samples", type=int, default=300)
    parser.add_argument("--drones", type=int, default=100)
    parser.add_argument("--cprofile", default="", help="write the threads' cProfile here")
    options = parser.parse_args()
    bench_ground.setup_django()
    bench = bench_ground._set_up()
    recorder = Recorder()
    try:
        env = private_ground.ground_env(bench.db_name, bench.broker)
        bench.processes.append(Supervised("gateway", gateway_argv(), env).start())
        names = bench.names[: options.drones]
        for name in names:
            bench.responders.append(
                bench_ground.Responder(name, bench.passwords[name], bench.broker.port)
            )
        bench_ground._wait_online(bench.responders)
        bare = bench_ground.bare_mqtt_rtt(bench.broker.port, bench.ground_password, names, 300)
        instrument(recorder)
        recorder.profile = cProfile.Profile() if options.cprofile else None
        loop = new_loop()
        times = loop.run_until_complete(
            commands(recorder, names, bench.token, options.command, options.samples)
        )
        report(recorder, times, bare, options.samples)
        if recorder.profile is not None:
            recorder.profile.dump_stats(options.cprofile)
        from workers import direct

        direct.close()  # before its event loop closes: the link resolves futures there
        loop.close()
    finally:
        bench_ground._tear_down(bench)


if __name__ == "__main__":
    main()

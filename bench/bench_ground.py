"""Ground link: command round trip REST → drone → REST, and heartbeat rate.

    .venv/bin/python -m bench.bench_ground

Runs against the test profile's services (`scripts/services.sh start test`): its own
database `test_bench_ground` (created and dropped here), its own Redis database, a
private Mosquitto, the real gateway (`manage.py gateway`) and the real ASGI app
(uvicorn) as subprocesses, with N drones provisioned through fleet.credentials.

Drones are lightweight MQTT responders in this process (one paho client each, TCP_NODELAY,
answering `<id>/control/in` on `<id>/control/out` as the agent does): 100 full
simulator + agent pairs do not fit on two cores next to the ground, and the agent's own
command execution time is not what this measures.

Keys:
- ground.command_rtt_p50_1 / _p50_100 / _p99_100: `POST /api/v1/drones/{id}/commands/`
  (a personal token, as `POST /api/v1/token/` gives; keep-alive) until the drone's reply
  is in the HTTP answer, with 1 and 100 drones connected. Baseline: a bare MQTT
  request/response through the same broker (a ground paho client publishing to
  `<id>/control/in` and receiving `<id>/control/out`).
  The web process sends over its own broker connection (workers.direct), opened at its
  first command: the warm-up requests, not measured, cover that.
- ground.heartbeats_per_s: heartbeats one gateway validates and stores per second under a
  flood (read by its own MQTT reader, stored a batch per statement). Baseline: the raw
  rate one paho client receives the same flood doing nothing with it (a separate
  process, like the gateway). Also written with it: the load average, and the CPU time
  per heartbeat of the gateway's process against the raw client's (steadier than rates
  when other work shares the cores).
"""

from __future__ import annotations

import json
import os
import socket
import statistics
import subprocess
import sys
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
from workers.ground import gateway_argv

ROOT = Path(__file__).resolve().parents[1]
DB_NAME = "bench_ground"
REDIS_DB = 11
SAMPLES_1 = int(os.environ.get("BENCH_GROUND_SAMPLES", 300))
SAMPLES_100 = int(os.environ.get("BENCH_GROUND_SAMPLES_100", 500))
FLOOD_S = 5.0
HOME = (38.736946, -9.142685)


def setup_django() -> None:
    # BENCH_GROUND_SETTINGS compares another settings module (e.g. a pooled database).
    os.environ["DJANGO_SETTINGS_MODULE"] = os.environ.get(
        "BENCH_GROUND_SETTINGS", "config.settings.test"
    )
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    os.environ["TEST_DB_NAME"] = f"test_{DB_NAME}{'_' + worker if worker else ''}"
    # One token sends commands back to back as fast as the drones answer, far past what
    # an operator sends: the web process's rate limit (COMMAND_RATE) is raised, not
    # removed, so its cost (one cache read and write per command) stays in the figure.
    os.environ.setdefault("COMMAND_RATE", "1000000/s")
    parts = urlsplit(test_profile_env()["REDIS_URL"])
    os.environ["REDIS_URL"] = urlunsplit(parts._replace(path=f"/{REDIS_DB}"))
    import django

    django.setup()


def _record(key: str, **figure: object) -> None:
    """Into bench/results.json only for the project's own settings; a comparison run with
    BENCH_GROUND_SETTINGS just prints."""
    from bench.common import record

    if "BENCH_GROUND_SETTINGS" in os.environ:
        print(key, figure["value"], figure["unit"], flush=True)
        return
    record(key, **figure)  # type: ignore[arg-type]


def drone_id(i: int) -> str:
    return f"BENCH_G{i:03d}"


def _client(user: str, password: str, port: int, client_id: str):  # type: ignore[no-untyped-def]
    import paho.mqtt.client as mqtt

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id)
    client.username_pw_set(user, password)
    connected = threading.Event()

    def on_connect(c, userdata, flags, reason_code, properties):  # type: ignore[no-untyped-def]
        c.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        connected.set()

    client.on_connect = on_connect
    client.connect("127.0.0.1", port, keepalive=30)
    client.loop_start()
    if not connected.wait(10):
        raise RuntimeError(f"{user} could not connect")
    return client


class Responder:
    """A drone's control side: every request answered at once, like the agent's replies."""

    def __init__(self, name: str, password: str, port: int) -> None:
        self.name = name
        self.client = _client(name, password, port, f"resp-{name}")
        self.client.on_message = self._on_message
        done = threading.Event()
        self.client.on_subscribe = lambda *args: done.set()
        self.client.subscribe(f"{name}/control/in", qos=1)
        done.wait(5)

    def _on_message(self, client, userdata, message) -> None:  # type: ignore[no-untyped-def]
        request = json.loads(message.payload)
        reply = {
            "request_id": request["request_id"],
            "command": request["command"],
            "ok": True,
            "result": {},
            "error": None,
            "ts": time.time(),
        }
        client.publish(f"{self.name}/control/out", json.dumps(reply), qos=1)

    def heartbeat(self) -> None:
        self.client.publish(f"{self.name}/heartbeats/out", json.dumps(heartbeat(self.name)), qos=1)

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def heartbeat(name: str) -> dict:
    return {
        "type": "heartbeat",
        "drone_id": name,
        "ts": time.time(),
        "position": {"lat": HOME[0], "lon": HOME[1], "alt": 0.0},
        "battery": {"voltage": 16.4, "remaining": 0.95},
        "armed": False,
        "airborne": False,
        "flight_mode": "POSITIONHOLD",
        "mission": None,
        "fc": {"protocol": "uavtalk", "connected": True},
    }


def bare_mqtt_rtt(port: int, ground_password: str, names: list[str], samples: int) -> list[float]:
    """Ground publishes a control request, the responder answers, the ground receives it."""
    ground = _client("ground", ground_password, port, "bench-ground-bare")
    got = threading.Event()
    ground.on_message = lambda c, u, m: got.set()
    subscribed = threading.Event()
    ground.on_subscribe = lambda *args: subscribed.set()
    ground.subscribe("+/control/out", qos=1)
    subscribed.wait(5)
    rtts = []
    for i in range(samples + 20):
        name = names[i % len(names)]
        request = {
            "request_id": os.urandom(16).hex(),
            "command": "arm",
            "params": {},
            "ts": time.time(),
        }
        got.clear()
        began = time.perf_counter()
        ground.publish(f"{name}/control/in", json.dumps(request), qos=1)
        if not got.wait(5):
            raise RuntimeError("no bare reply")
        if i >= 20:
            rtts.append((time.perf_counter() - began) * 1000)
    ground.disconnect()
    ground.loop_stop()
    return rtts


class Http:
    """One keep-alive HTTP connection (the standard library's: its own cost per request is
    a small part of a round trip, as a bare paho client's is of the baseline's)."""

    def __init__(self, base_url: str, token: str) -> None:
        import http.client

        parts = urlsplit(base_url)
        self.connection = http.client.HTTPConnection(parts.hostname, parts.port, timeout=20)
        self.headers = {"Authorization": f"Token {token}", "Content-Type": "application/json"}

    def call(self, method: str, path: str, body: str | None = None) -> tuple[int, bytes]:
        self.connection.request(method, path, body=body, headers=self.headers)
        response = self.connection.getresponse()
        return response.status, response.read()


def rest_rtt(base_url: str, token: str, names: list[str], samples: int) -> list[float]:
    http = Http(base_url, token)
    body = json.dumps({"command": "arm", "params": {}})
    rtts = []
    for i in range(samples + 20):
        name = names[i % len(names)]
        began = time.perf_counter()
        status, content = http.call("POST", f"/api/v1/drones/{name}/commands/", body)
        elapsed = (time.perf_counter() - began) * 1000
        if status != 200 or not json.loads(content)["ok"]:
            raise RuntimeError(f"{name}: {status} {content[:200]!r}")
        if i >= 20:
            rtts.append(elapsed)
    return rtts


def rest_read_rtt(base_url: str, token: str, name: str, samples: int) -> list[float]:
    """The same HTTP stack without a drone: GET the drone's gear (token, drone, role)."""
    http = Http(base_url, token)
    rtts = []
    for i in range(samples + 20):
        began = time.perf_counter()
        status, content = http.call("GET", f"/api/v1/drones/{name}/gear/")
        if status != 200:
            raise RuntimeError(content[:200])
        if i >= 20:
            rtts.append((time.perf_counter() - began) * 1000)
    return rtts


def flood(port: int, ground_password: str, names: list[str], seconds: float) -> int:
    """Publish valid heartbeats as fast as paho will for `seconds`; returns how many."""
    publisher = _client("ground", ground_password, port, f"bench-flood-{time.monotonic_ns()}")
    payloads = [(f"{n}/heartbeats/out", json.dumps(heartbeat(n))) for n in names]
    sent = 0
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for topic, payload in payloads:
            publisher.publish(topic, payload, qos=0)
        sent += len(payloads)
        # Keep paho's own buffer bounded: the receiver, not the publisher, is measured.
        time.sleep(0.002)
    publisher.disconnect()
    publisher.loop_stop()
    return sent


RAW_RECEIVER = """
import json, socket, sys, threading, time
import paho.mqtt.client as mqtt
port, password, seconds = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])
count = [0]; first = [None]; cpu = [0.0]
def on_message(c, u, m):
    if first[0] is None: first[0] = time.perf_counter(); cpu[0] = time.process_time()
    count[0] += 1
def on_connect(c, u, f, rc, p):
    c.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    c.subscribe("$share/raw/+/heartbeats/out", qos=0)
c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="bench-raw")
c.username_pw_set("ground", password)
c.on_message = on_message; c.on_connect = on_connect
c.connect("127.0.0.1", port); c.loop_start()
print("ready", flush=True)
while first[0] is None: time.sleep(0.01)
time.sleep(seconds)
n = count[0]; elapsed = time.perf_counter() - first[0]; used = time.process_time() - cpu[0]
print(json.dumps({"rate": n / elapsed, "cpu_us": used / n * 1e6}), flush=True)
c.loop_stop()
"""


def gateway_counter(name: str) -> float:
    from workers.counters import snapshot

    return snapshot().get("gateway", {}).get(name, 0.0)


@dataclass
class Bench:
    """What one run set up: the broker, the drones' credentials, the ground processes."""

    broker: Any
    ground_password: str
    token: str
    names: list[str]
    passwords: dict[str, str]
    db_name: str
    processes: list[Supervised] = field(default_factory=list)
    responders: list[Responder] = field(default_factory=list)
    base_url: str = ""


def _set_up() -> Bench:
    """A test database, a private broker the settings point at, an operator and 100 drones."""
    from workers.counters import KEY_PREFIX
    from workers.counters import _client as counters_redis

    ground_password = "bench-ground"
    folder = Path(tempfile.mkdtemp(prefix="bench-ground-"))
    db_name, broker = private_ground.database_and_broker(folder, ground_password)
    counters_redis().delete(KEY_PREFIX + "gateway")
    names = [drone_id(i) for i in range(100)]
    _, token, passwords = private_ground.operator_and_drones(names)
    return Bench(broker, ground_password, token, names, passwords, db_name)


def _start_ground(bench: Bench) -> None:
    """The real gateway and the ASGI app, on the bench database and broker."""
    env = private_ground.ground_env(bench.db_name, bench.broker)
    bench.processes.append(Supervised("gateway", gateway_argv(), env).start())
    web = private_ground.start_web(env, 30)
    bench.processes.append(web)
    bench.base_url = web.url


def _measure_rtts(bench: Bench) -> tuple[dict[str, tuple[list[float], list[float]]], list[float]]:
    """REST and bare MQTT round trips with 1, then 100 drones connected; and with one
    connected, the same HTTP stack without a drone in the loop (for the summary)."""
    results: dict[str, tuple[list[float], list[float]]] = {}
    read: list[float] = []
    port = bench.broker.port
    for count in (1, 100):
        while len(bench.responders) < count:
            name = bench.names[len(bench.responders)]
            bench.responders.append(Responder(name, bench.passwords[name], port))
        active = bench.names[:count]
        _wait_online(bench.responders[:count])
        samples = SAMPLES_1 if count == 1 else SAMPLES_100
        bare = bare_mqtt_rtt(port, bench.ground_password, active, samples)
        rest = rest_rtt(bench.base_url, bench.token, active, samples)
        if count == 1:
            read = rest_read_rtt(bench.base_url, bench.token, active[0], samples)
        results[str(count)] = (rest, bare)
    return results, read


def _record_rtts(results: dict[str, tuple[list[float], list[float]]]) -> None:
    from bench.common import percentile

    (rest1, bare1), (rest100, bare100) = results["1"], results["100"]
    goal_p50 = "p50 overhead under 3x the bare MQTT round trip"
    for key, rest, bare, drones in (
        ("ground.command_rtt_p50_1", rest1, bare1, "1 drone"),
        ("ground.command_rtt_p50_100", rest100, bare100, "100 drones"),
    ):
        _record(
            key,
            value=statistics.median(rest),
            unit="ms",
            baseline_name=f"bare MQTT request/response p50, same broker, {drones}",
            baseline_value=statistics.median(bare),
            higher_is_better=False,
            goal=goal_p50,
        )
    _record(
        "ground.command_rtt_p99_100",
        value=percentile(rest100, 99),
        unit="ms",
        baseline_name="bare MQTT request/response p99, same broker, 100 drones",
        baseline_value=percentile(bare100, 99),
        higher_is_better=False,
        goal="p99 under 10 ms with 100 connected drones",
    )


def _measure_heartbeats(bench: Bench) -> tuple[float, float]:
    """(the gateway's heartbeat rate, the raw paho rate of the same flood)."""
    for responder in bench.responders:
        responder.stop()
    bench.responders.clear()
    port, password = bench.broker.port, bench.ground_password
    _wait_reading(port, password, bench.names)
    gateway = bench.processes[0]
    assert gateway.pid is not None
    gateway_rate, gateway_cpu = _gateway_heartbeat_rate(port, password, bench.names, gateway.pid)
    gateway.stop(10)  # the baseline receiver gets the broker and the CPU to itself
    raw_rate, raw_cpu = _raw_rate(port, password, bench.names)
    load = os.getloadavg()
    print(
        f"CPU per heartbeat: gateway {gateway_cpu:.1f} us, raw paho {raw_cpu:.1f} us; load {load}"
    )
    _record(
        "ground.heartbeats_per_s",
        value=gateway_rate,
        unit="heartbeats/s",
        baseline_name="raw paho receive rate of the same flood (one client, no work)",
        baseline_value=raw_rate,
        higher_is_better=True,
        goal="at least 0.8 of the raw paho rate",
        cpu_us_per_heartbeat={"gateway": gateway_cpu, "raw_paho": raw_cpu},
        load_average=load,
    )
    return gateway_rate, raw_rate


def _summary(results: dict, read: list[float], rates: tuple[float, float]) -> str:
    from bench.common import percentile

    (rest1, bare1), (rest100, bare100) = results["1"], results["100"]
    figures = {
        "rest_p50_1": statistics.median(rest1),
        "rest_read_p50_no_drone": statistics.median(read),
        "bare_p50_1": statistics.median(bare1),
        "rest_p50_100": statistics.median(rest100),
        "rest_p99_100": percentile(rest100, 99),
        "bare_p50_100": statistics.median(bare100),
        "bare_p99_100": percentile(bare100, 99),
        "gateway_heartbeats_per_s": rates[0],
        "raw_paho_per_s": rates[1],
    }
    return json.dumps(figures, indent=1)


def _tear_down(bench: Bench) -> None:
    from django.db import connection

    for responder in bench.responders:
        responder.stop()
    for process in bench.processes:
        process.stop(10)
    bench.broker.stop()
    connection.creation.destroy_test_db(bench.db_name, verbosity=0)


# BENCH_GROUND_PARTS=heartbeats (or rtt) runs one part only: both by default.
PARTS = set(os.environ.get("BENCH_GROUND_PARTS", "rtt,heartbeats").split(","))


def main() -> None:
    setup_django()
    bench = _set_up()
    try:
        _start_ground(bench)
        if "rtt" in PARTS:
            results, read = _measure_rtts(bench)
            _record_rtts(results)
        if "heartbeats" in PARTS:
            rates = _measure_heartbeats(bench)
            print(f"heartbeats: gateway {rates[0]:.0f}/s, raw paho {rates[1]:.0f}/s", flush=True)
        if PARTS >= {"rtt", "heartbeats"}:
            print(_summary(results, read, rates))
    finally:
        _tear_down(bench)


def _wait_online(responders: list[Responder], timeout: float = 30) -> None:
    """Heartbeat until the gateway (still starting, maybe) has marked them all online."""
    from fleet.models import Drone

    names = [r.name for r in responders]

    def online() -> bool:
        if Drone.objects.filter(drone_id__in=names, online=True).count() == len(names):
            return True
        for responder in responders:
            responder.heartbeat()
        return False

    if not wait_for(online, timeout, interval=0.5):
        raise RuntimeError("drones did not come online (is the gateway running?)")


def _wait_reading(port: int, password: str, names: list[str], timeout: float = 60) -> None:
    """Heartbeat every drone until the gateway (still starting, maybe) has marked them all
    online, so the flood is not measured against a gateway that is not reading yet."""
    from fleet.models import Drone

    def online() -> bool:
        if Drone.objects.filter(drone_id__in=names, online=True).count() == len(names):
            return True
        flood(port, password, names, 0.01)
        return False

    if not wait_for(online, timeout, interval=0.5):
        raise RuntimeError("the gateway did not store heartbeats (is it running?)")


def _cpu_seconds(pid: int) -> float:
    """User and system CPU time a process (all its threads) has used so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _gateway_heartbeat_rate(
    port: int, password: str, names: list[str], pid: int
) -> tuple[float, float]:
    """Handled heartbeats per second over a window in the middle of the flood, and the
    gateway's CPU microseconds per heartbeat over the whole flood and its drain."""
    samples: list[tuple[float, float]] = []
    stop = threading.Event()

    def watch() -> None:
        while not stop.wait(0.5):
            samples.append((time.monotonic(), gateway_counter("handled")))

    before, cpu_before = gateway_counter("handled"), _cpu_seconds(pid)
    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    flood(port, password, names, FLOOD_S)
    stop.set()
    watcher.join()
    # Counters flush once a second: take the steady part, skipping the ramp-up.
    (t0, n0), (t1, n1) = samples[2], samples[-1]
    rate = (n1 - n0) / (t1 - t0)
    # Drained once the count stops moving for two flushes.
    counts = [gateway_counter("handled")]
    while len(counts) < 3 or counts[-1] != counts[-3]:
        time.sleep(1.0)
        counts.append(gateway_counter("handled"))
    cpu = (_cpu_seconds(pid) - cpu_before) / max(1.0, counts[-1] - before) * 1e6
    return rate, cpu


def _raw_rate(port: int, password: str, names: list[str]) -> tuple[float, float]:
    """The raw client's rate, and its CPU microseconds per message."""
    receiver = subprocess.Popen(
        [sys.executable, "-c", RAW_RECEIVER, str(port), password, str(FLOOD_S - 1.5)],
        stdout=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    assert receiver.stdout is not None
    receiver.stdout.readline()
    time.sleep(0.3)
    flood(port, password, names, FLOOD_S)
    line = receiver.stdout.readline()
    receiver.wait(10)
    figures = json.loads(line)
    return figures["rate"], figures["cpu_us"]


if __name__ == "__main__":
    main()

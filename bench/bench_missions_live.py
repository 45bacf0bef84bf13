"""Replacement latency: a CRITICAL alarm reaching the broker → the replacement
drone accepting its mission, with 1 and with 100 candidate drones connected.

    .venv/bin/python -m bench.bench_missions_live

Runs against the test profile's services (`scripts/services.sh start test`): its own
database `test_bench_missions_live` (created and dropped here), its own Redis database
(outbox, Celery broker, channel layer), a private Mosquitto, the real gateway
(`manage.py gateway`) and a real Celery worker as subprocesses. Drones are MQTT
emulators in this process: each sends heartbeats every second and answers a mission
start the way the agent's mission worker does (decode and validate the payload with
`onboard.protocol`, then publish `accepted` with the decode time). The failing drone
publishes the alarm; a ground observer subscribed to `+/mission/out` stops the clock
when the replacement's `accepted` arrives.

Baseline in the same run: a bare MQTT publish → receive through the same broker.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

ROOT = Path(__file__).resolve().parents[1]
DB_NAME = "bench_missions_live"
REDIS_DB = 10
SAMPLES = int(os.environ.get("BENCH_MISSIONS_SAMPLES", 15))
WARMUP = 2
FLEETS = (1, 100)
HOME = (40.6303, -8.6575)


def _test_env() -> dict[str, str]:
    values = {}
    for line in (ROOT / ".data" / "test" / "env").read_text().splitlines():
        if "=" in line and not line.startswith("#"):
            key, value = line.split("=", 1)
            values[key.strip()] = value.strip()
    return values


def _redis_url() -> str:
    parts = urlsplit(_test_env()["REDIS_URL"])
    return urlunsplit(parts._replace(path=f"/{REDIS_DB}"))


def setup_django() -> None:
    os.environ["DJANGO_SETTINGS_MODULE"] = "config.settings.test"
    os.environ["TEST_DB_NAME"] = f"test_{DB_NAME}"
    # Our own Redis database: outbox, Celery broker and channel layer of this run only.
    os.environ["REDIS_URL"] = _redis_url()
    os.environ.pop("CELERY_BROKER_URL", None)
    import django

    django.setup()


def drone_id(i: int) -> str:
    return f"BENCH_R{i:03d}"


class Emulator:
    """One drone's MQTT side: heartbeats, and `accepted` for every mission start."""

    def __init__(
        self, port: int, name: str, password: str, position: tuple[float, float], on_start=None
    ) -> None:  # type: ignore[no-untyped-def]
        import paho.mqtt.client as mqtt

        from onboard import protocol

        self.protocol = protocol
        self.name = name
        self.position = position
        self.on_start = on_start
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"emu-{name}")
        self.client.username_pw_set(name, password)
        self.connected = threading.Event()
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port, keepalive=30)
        self.client.loop_start()

    def _on_connect(self, client, userdata, flags, rc, properties) -> None:  # type: ignore[no-untyped-def]
        import socket

        client.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.subscribe(f"{self.name}/+/in", qos=1)
        self.connected.set()

    def _on_message(self, client, userdata, message) -> None:  # type: ignore[no-untyped-def]
        if not message.topic.endswith("/mission/in"):
            return
        request = self.protocol.parse_mission_request(json.loads(message.payload))
        if not isinstance(request, self.protocol.MissionStart):
            return
        began = time.perf_counter()
        payload = self.protocol.decode_mission_payload(request.payload)
        decode_ms = (time.perf_counter() - began) * 1000
        accepted = self.protocol.MissionProgress(
            payload.mission_id,
            payload.assignment_id,
            "accepted",
            decode_ms,
            request_id=request.request_id,
        )
        client.publish(f"{self.name}/mission/out", self.protocol.encode(accepted), qos=1)

    def heartbeat(self) -> None:
        message = {
            "type": "heartbeat",
            "drone_id": self.name,
            "ts": time.time(),
            "position": {"lat": self.position[0], "lon": self.position[1], "alt": 0.0},
            "battery": {"voltage": 16.4, "remaining": 0.95},
            "armed": False,
            "airborne": False,
            "flight_mode": "POSITIONHOLD",
            "mission": None,
            "fc": {"protocol": "uavtalk", "connected": True},
        }
        self.client.publish(f"{self.name}/heartbeats/out", json.dumps(message), qos=0)

    def alarm(self, mission_id: str, assignment_id: str) -> None:
        message = self.protocol.Alarm(
            level="CRITICAL",
            message="battery below 25 %",
            position=self.protocol.Position(self.position[0], self.position[1], 10.0),
            mission_id=mission_id,
            assignment_id=assignment_id,
            index=3,
        )
        self.client.publish(f"{self.name}/alarms/out", self.protocol.encode(message), qos=1)

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class Observer:
    """The ground's view of the broker: the first `accepted` from a given drone set."""

    def __init__(self, port: int, password: str) -> None:
        import paho.mqtt.client as mqtt

        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="bench-observer")
        self.client.username_pw_set("ground", password)
        self.lock = threading.Lock()
        self.waiting: tuple[set[str], threading.Event] | None = None
        self.arrived = 0.0
        self.bare: threading.Event = threading.Event()
        ready = threading.Event()

        def on_connect(client, userdata, flags, rc, properties):  # type: ignore[no-untyped-def]
            client.subscribe([("+/mission/out", 1), ("bench/echo", 1)])
            ready.set()

        self.client.on_connect = on_connect
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()
        assert ready.wait(5)
        time.sleep(0.2)

    def _on_message(self, client, userdata, message) -> None:  # type: ignore[no-untyped-def]
        now = time.perf_counter()
        if message.topic == "bench/echo":
            self.arrived = now
            self.bare.set()
            return
        sender = message.topic.split("/", 1)[0]
        data = json.loads(message.payload)
        with self.lock:
            if self.waiting and sender in self.waiting[0] and data.get("status") == "accepted":
                self.arrived = now
                self.waiting[1].set()

    def expect_accept_from(self, drones: set[str]) -> threading.Event:
        event = threading.Event()
        with self.lock:
            self.waiting = (drones, event)
        return event


def start_broker(directory: Path, users: dict[str, str]):  # type: ignore[no-untyped-def]
    from tests.support.mosquitto import GROUND_AND_DRONES_ACL, MOSQUITTO_PASSWD, Broker, free_port

    class FastBroker(Broker):
        """All users hashed by one mosquitto_passwd -U call."""

        def write_config(self) -> Path:
            everyone, self.users = self.users, {}
            conf = super().write_config()
            self.users = everyone
            passwd = self.directory / "passwd"
            passwd.write_text("".join(f"{u}:{p}\n" for u, p in everyone.items()))
            subprocess.run([MOSQUITTO_PASSWD, "-U", str(passwd)], check=True)
            return conf

    return FastBroker(directory, free_port(), users, GROUND_AND_DRONES_ACL).start()


def spawn(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
    with open(log, "w") as handle:
        return subprocess.Popen(args, cwd=ROOT, env=env, stdout=handle, stderr=subprocess.STDOUT)


def bare_round_trip(port: int, password: str, observer: Observer, samples: int = 100) -> float:
    """Median publish → receive through the same broker (QoS 1, TCP_NODELAY)."""
    import statistics

    import paho.mqtt.client as mqtt

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="bench-echo")
    client.username_pw_set("ground", password)
    client.connect("127.0.0.1", port)
    client.loop_start()
    time.sleep(0.2)
    times = []
    for _ in range(samples):
        observer.bare.clear()
        started = time.perf_counter()
        client.publish("bench/echo", b"x" * 200, qos=1)
        assert observer.bare.wait(5)
        times.append(observer.arrived - started)
    client.disconnect()
    client.loop_stop()
    return statistics.median(times)


def measure(fleet_size: int, broker, passwords: dict[str, str], observer: Observer) -> dict:  # type: ignore[no-untyped-def]
    """Median, p95 and the ground's own decision time for one fleet size."""
    import statistics

    from django.db import connections

    from bench.common import percentile
    from fleet.models import Drone, Organisation
    from missions.geo import LocalFrame
    from missions.models import Event
    from missions.services import create_mission, start_mission, stop_mission

    frame = LocalFrame(*HOME)
    organisation = Organisation.objects.get(slug="bench")
    names = [drone_id(i) for i in range(fleet_size + 1)]  # the failing one + candidates
    emulators = []
    for i, name in enumerate(names):
        # Candidates on a line north of the failing drone, 15 m apart.
        position = frame.point_to_latlon([15.0 * i, 0.0])
        emulators.append(Emulator(broker.port, name, passwords[name], position))
    beating = threading.Event()

    def beat() -> None:
        while not beating.wait(1.0):
            for emulator in emulators:
                emulator.heartbeat()

    for emulator in emulators:
        assert emulator.connected.wait(10)
        emulator.heartbeat()
    beater = threading.Thread(target=beat, daemon=True)
    beater.start()
    deadline = time.monotonic() + 30
    while Drone.objects.filter(drone_id__in=names, online=True).count() < len(names):
        assert time.monotonic() < deadline, "emulated drones did not come online"
        time.sleep(0.1)
    failing = emulators[0]
    candidates = {name for name in names[1:]}
    waypoints = [frame.point_to_latlon([10.0 * k, 5.0]) for k in range(6)]
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10}}]
    for lat, lon in waypoints:
        steps += [
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "wait_for_flight"},
        ]
    steps.append({"command": "land"})
    latencies, decisions = [], []
    for sample in range(WARMUP + SAMPLES):
        mission = create_mission(organisation=organisation, name=f"bench {sample}", steps=steps)
        failing_drone = Drone.objects.get(drone_id=failing.name)
        assignment = start_mission(mission, drone=failing_drone).assignment
        time.sleep(0.3)  # the failing drone accepts its own start first
        accepted = observer.expect_accept_from(candidates)
        started = time.perf_counter()
        failing.alarm(str(mission.pk), str(assignment.pk))
        assert accepted.wait(10), f"no replacement accepted (fleet {fleet_size})"
        elapsed = observer.arrived - started
        if sample >= WARMUP:
            latencies.append(elapsed)
            decision = None
            for _ in range(50):
                decision = Event.objects.filter(
                    mission=mission, data__decision="replacement"
                ).first()
                if decision:
                    break
                time.sleep(0.02)
            if decision is not None:
                decisions.append(decision.data.get("since_alarm_ms", 0.0) / 1000)
        stop_mission(mission, reason="benchmark sample done")
        time.sleep(0.2)
    beating.set()
    beater.join()
    for emulator in emulators:
        emulator.stop()
    connections.close_all()
    return {
        "median": statistics.median(latencies),
        "p95": percentile(latencies, 95),
        "decision_median": statistics.median(decisions) if decisions else None,
    }


def main() -> int:
    setup_django()
    from django.conf import settings
    from django.db import connection

    from bench.common import record
    from fleet.models import Drone, Organisation
    from tests.support.celery_worker import worker_argv
    from tests.support.processes import stop_process
    from workers import outbox

    outbox.sync_redis().flushdb()
    original_name = connection.settings_dict["NAME"]
    db_name = connection.creation.create_test_db(verbosity=0, autoclobber=True, keepdb=False)
    workdir = Path(tempfile.mkdtemp(prefix="bench-missions-"))
    processes: list[subprocess.Popen] = []
    broker = None
    try:
        passwords = {drone_id(i): uuid.uuid4().hex for i in range(max(FLEETS) + 1)}
        ground_password = uuid.uuid4().hex
        broker = start_broker(workdir / "mosquitto", {"ground": ground_password, **passwords})
        # The outbox is per broker: this process, the gateway and the worker agree on it.
        settings.MQTT_URL = broker.url_for("ground")
        organisation = Organisation.objects.create(name="Bench", slug="bench")
        Drone.objects.bulk_create(
            Drone(organisation=organisation, drone_id=name) for name in passwords
        )
        env = dict(
            os.environ,
            TEST_WORKER_DB_NAME=db_name,
            MQTT_URL=broker.url_for("ground"),
            REDIS_URL=settings.REDIS_URL,
            PYTHONUNBUFFERED="1",
        )
        processes.append(
            spawn([sys.executable, "manage.py", "gateway"], env, workdir / "gateway.log")
        )
        processes.append(
            spawn(
                worker_argv(f"bench-{uuid.uuid4().hex[:6]}@%h", chatter=False),
                env,
                workdir / "worker.log",
            )
        )
        observer = Observer(broker.port, ground_password)
        time.sleep(3)  # gateway subscribed, worker ready
        baseline = bare_round_trip(broker.port, ground_password, observer)
        for size in FLEETS:
            figures = measure(size, broker, passwords, observer)
            record(
                f"missions.replacement_latency_{size}",
                value=round(figures["median"], 4),
                unit="s",
                baseline_name="bare MQTT publish→receive, same broker (median)",
                baseline_value=round(baseline, 5),
                higher_is_better=False,
                goal="under 0.5 s on loopback",
                p95=round(figures["p95"], 4),
                ground_decision_median_s=figures["decision_median"],
                candidates=size,
                samples=SAMPLES,
            )
    finally:
        for process in processes:
            stop_process(process, 15)
        if broker is not None:
            broker.stop()
        from django.db import connections

        connections.close_all()
        connection.creation.destroy_test_db(original_name, verbosity=0)
        outbox.sync_redis().flushdb()
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

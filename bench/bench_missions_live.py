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

import contextlib
import json
import os
import shutil
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

from bench.common import test_profile_env
from runtime.processes import Supervised, free_port, python_env, wait_for
from workers.ground import gateway_argv, worker_argv

DB_NAME = "bench_missions_live"
REDIS_DB = 10
SAMPLES = int(os.environ.get("BENCH_MISSIONS_SAMPLES", 15))
WARMUP = 2
FLEETS = (1, 100)
HOME = (40.6303, -8.6575)


def _redis_url() -> str:
    parts = urlsplit(test_profile_env()["REDIS_URL"])
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
    from workers.mosquitto import GROUND_AND_DRONES_ACL, Broker

    return Broker(directory, free_port(), users, GROUND_AND_DRONES_ACL).start()


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


class Fleet:
    """The failing drone and `size` candidates on a line north of it, 15 m apart, beating
    every second until stopped."""

    def __init__(self, size: int, broker, passwords: dict[str, str]) -> None:  # type: ignore[no-untyped-def]
        from missions.geo import LocalFrame

        self.frame = LocalFrame(*HOME)
        self.names = [drone_id(i) for i in range(size + 1)]
        self.emulators = [
            Emulator(broker.port, name, passwords[name], self.frame.point_to_latlon([15.0 * i, 0]))
            for i, name in enumerate(self.names)
        ]
        self._stopping = threading.Event()
        self._beater = threading.Thread(target=self._beat, daemon=True)

    @property
    def failing(self) -> Emulator:
        return self.emulators[0]

    def start(self) -> Fleet:
        from fleet.models import Drone

        for emulator in self.emulators:
            assert emulator.connected.wait(10)
            emulator.heartbeat()
        self._beater.start()

        def online() -> bool:
            rows = Drone.objects.filter(drone_id__in=self.names, online=True)
            return rows.count() == len(self.names)

        assert wait_for(online, 30, interval=0.1), "emulated drones did not come online"
        return self

    def _beat(self) -> None:
        while not self._stopping.wait(1.0):
            for emulator in self.emulators:
                emulator.heartbeat()

    def stop(self) -> None:
        self._stopping.set()
        self._beater.join()
        for emulator in self.emulators:
            emulator.stop()


def survey_steps(frame) -> list[dict]:  # type: ignore[no-untyped-def]
    """Arm, take off, six waypoints 10 m apart, land."""
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10}}]
    for k in range(6):
        lat, lon = frame.point_to_latlon([10.0 * k, 5.0])
        steps += [
            {"command": "navigate", "params": {"lat": lat, "lon": lon}},
            {"command": "wait_for_flight"},
        ]
    return [*steps, {"command": "land"}]


def one_sample(fleet: Fleet, observer: Observer, steps: list[dict], n: int) -> tuple[float, Any]:
    """Start a mission on the failing drone, raise its alarm: (seconds until a candidate
    accepted, the mission)."""
    from fleet.models import Drone, Organisation
    from missions.creation import create_mission
    from missions.startstop import start_mission

    organisation = Organisation.objects.get(slug="bench")
    mission = create_mission(organisation=organisation, name=f"bench {n}", steps=steps)
    failing_drone = Drone.objects.get(drone_id=fleet.failing.name)
    assignment = start_mission(mission, drone=failing_drone).assignment
    time.sleep(0.3)  # the failing drone accepts its own start first
    accepted = observer.expect_accept_from(set(fleet.names[1:]))
    started = time.perf_counter()
    fleet.failing.alarm(str(mission.pk), str(assignment.pk))
    assert accepted.wait(10), f"no replacement accepted (fleet {len(fleet.names) - 1})"
    return observer.arrived - started, mission


def decision_seconds(mission) -> float | None:  # type: ignore[no-untyped-def]
    """The ground's own time from alarm to decision, once the decision is on record."""
    from missions.models import Event

    def decided():  # type: ignore[no-untyped-def]
        return Event.objects.filter(mission=mission, data__decision="replacement").first()

    decision = wait_for(decided, 1.0, interval=0.02)
    return decision.data.get("since_alarm_ms", 0.0) / 1000 if decision is not None else None


def measure(fleet_size: int, broker, passwords: dict[str, str], observer: Observer) -> dict:  # type: ignore[no-untyped-def]
    """Median, p95 and the ground's own decision time for one fleet size."""
    import statistics

    from django.db import connections

    from bench.common import percentile
    from missions.startstop import stop_mission

    fleet = Fleet(fleet_size, broker, passwords).start()
    steps = survey_steps(fleet.frame)
    latencies, decisions = [], []
    for sample in range(WARMUP + SAMPLES):
        elapsed, mission = one_sample(fleet, observer, steps, sample)
        if sample >= WARMUP:
            latencies.append(elapsed)
            decision = decision_seconds(mission)
            if decision is not None:
                decisions.append(decision)
        stop_mission(mission, reason="benchmark sample done")
        time.sleep(0.2)
    fleet.stop()
    connections.close_all()
    return {
        "median": statistics.median(latencies),
        "p95": percentile(latencies, 95),
        "decision_median": statistics.median(decisions) if decisions else None,
    }


def start_ground(broker, db_name: str, workdir: Path) -> list[Supervised]:  # type: ignore[no-untyped-def]
    """The real gateway and a Celery worker on the bench database, broker and Redis."""
    from django.conf import settings

    env = python_env(
        TEST_WORKER_DB_NAME=db_name,
        MQTT_URL=broker.url_for("ground"),
        REDIS_URL=settings.REDIS_URL,
        PYTHONUNBUFFERED="1",
    )
    worker = worker_argv(f"bench-{uuid.uuid4().hex[:6]}@%h", chatter=False)
    return [
        Supervised("gateway", gateway_argv(), env, workdir / "gateway.log").start(),
        Supervised("worker", worker, env, workdir / "worker.log").start(),
    ]


def record_latency(size: int, figures: dict, baseline: float) -> None:
    from bench.common import record

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


def run(db_name: str, workdir: Path, stack: contextlib.ExitStack) -> None:
    """Broker, drones, ground; then the baseline and each fleet size, recorded."""
    from django.conf import settings

    from fleet.models import Drone, Organisation

    passwords = {drone_id(i): uuid.uuid4().hex for i in range(max(FLEETS) + 1)}
    ground_password = uuid.uuid4().hex
    broker = start_broker(workdir / "mosquitto", {"ground": ground_password, **passwords})
    stack.callback(broker.stop)
    # The outbox is per broker: this process, the gateway and the worker agree on it.
    settings.MQTT_URL = broker.url_for("ground")
    organisation = Organisation.objects.create(name="Bench", slug="bench")
    Drone.objects.bulk_create(Drone(organisation=organisation, drone_id=name) for name in passwords)
    for process in start_ground(broker, db_name, workdir):
        stack.callback(process.stop, 15)
    observer = Observer(broker.port, ground_password)
    time.sleep(3)  # gateway subscribed, worker ready
    baseline = bare_round_trip(broker.port, ground_password, observer)
    for size in FLEETS:
        record_latency(size, measure(size, broker, passwords, observer), baseline)


def main() -> int:
    setup_django()
    from django.db import connection, connections

    from workers import outbox

    outbox.sync_redis().flushdb()
    original_name = connection.settings_dict["NAME"]
    db_name = connection.creation.create_test_db(verbosity=0, autoclobber=True, keepdb=False)
    workdir = Path(tempfile.mkdtemp(prefix="bench-missions-"))
    try:
        with contextlib.ExitStack() as stack:  # stops the ground, then the broker
            run(db_name, workdir, stack)
    finally:
        connections.close_all()
        connection.creation.destroy_test_db(original_name, verbosity=0)
        outbox.sync_redis().flushdb()
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

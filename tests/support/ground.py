"""Replicated ground processes for tests (workers.ground on the test database), simulated
drones (firmware.sim.fleet), a private Redis, and what a user does against them.

Every process reads the database pytest-django created (TEST_WORKER_DB_NAME, see
config/settings/test.py) and gets the same environment: the broker settings (a private
Mosquitto, or a RabbitCluster's `settings_env()`), a REDIS_URL, and a Celery queue of its
own, so other suites running against the same Redis never take our tasks.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from firmware.sim.fleet import Drone, start_drone
from runtime.processes import Supervised, free_port, python_env
from runtime.processes import wait_for as poll
from workers import ground as replicas


def wait_for(predicate: Callable[[], object], timeout: float, interval: float = 0.1) -> object:
    """Polls every 0.1 s: the fault tests' timing (when a process is killed) relies on it."""
    return poll(predicate, timeout, interval)


def ground_processes(
    directory: Path, database_name: str, env: dict[str, str] | None = None
) -> replicas.GroundProcesses:
    """workers.ground.GroundProcesses on the test settings and database, with a Celery
    queue of its own (set it as the test process's default queue too when the test sends
    tasks). `env` overrides (MQTT_URL, MQTT_BROKER, REDIS_URL, ...) come last."""
    queue = f"repl-{uuid.uuid4().hex[:10]}"
    base = python_env(
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=database_name,
        PYTHONUNBUFFERED="1",
        CELERY_TASK_DEFAULT_QUEUE=queue,
    )
    # Playwright's tests set this in the pytest process; ground processes are not async-unsafe.
    base.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)
    base.update(env or {})
    return replicas.GroundProcesses(directory, base, queue=queue, client_prefix=queue)


# -- a private Redis ----------------------------------------------------------------------


class PrivateRedis:
    """A throw-away redis-server on a free port (the suite's Redis is shared by everyone
    running tests: a test that restarts Redis must restart its own). No persistence, like
    a Redis that lost its memory."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        argv = ["redis-server", "--port", str(self.port), "--bind", "127.0.0.1",
                "--save", "", "--appendonly", "no", "--dir", str(self.directory)]  # fmt: skip
        self.process = Supervised("redis", argv, None, self.directory / "redis.log", port=self.port)

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self, timeout: float = 10.0) -> PrivateRedis:
        self.process.start().wait_ready(timeout)
        return self

    def stop(self) -> None:
        self.process.stop(10)


# -- a replicated ground with simulated drones, for end-to-end scenarios ------------------

GROUND_PASSWORD = "ground-repl-password"
# Simulated seconds per real second: a 15-waypoint survey takes about 15 s.
TIME_SCALE = 20.0
HOME_ALT_MSL = 12.0
# Our own Redis database on the suite's Redis: other suites' gateways, counters and
# channel layers use the default one at the same time.
REDIS_DB = 13
# Knobs every scenario ground runs with: the beat's resume and sweep every second, and a
# visibility timeout short enough that a killed worker's task runs again within seconds
# (every task here takes well under a second).
FAST_ENV = {
    "MISSIONS_RESUME_INTERVAL_S": "1",
    "OFFLINE_SWEEP_INTERVAL_S": "1",
    "CELERY_VISIBILITY_TIMEOUT": "6",
}


def redis_url_with_db(url: str, db: int) -> str:
    from urllib.parse import urlsplit, urlunsplit

    return urlunsplit(urlsplit(url)._replace(path=f"/{db}"))


@dataclass
class ReplicatedGround:
    """The ground processes, the broker's addresses for drones, and the drones started."""

    processes: replicas.GroundProcesses
    directory: Path
    drone_url: Callable[[str, str], str]  # (drone id, password) → the agent's --broker
    drones: dict[str, Drone] = field(default_factory=dict)
    passwords: dict[str, str] = field(default_factory=dict)
    broker: object = None
    time_scale: float = TIME_SCALE

    def provision(self, drone_id: str, organisation_slug: str) -> str:
        """Create the drone with broker credentials; its --broker URL."""
        from fleet import credentials

        creds = credentials.provision(drone_id, organisation_slug)
        self.passwords[drone_id] = creds.password
        return self.drone_url(drone_id, creds.password)

    def add_drone(
        self, drone_id: str, organisation_slug: str, *, north: float = 0.0, east: float = 0.0
    ) -> Drone:
        from tests.missions.planning import point_at

        url = self.provision(drone_id, organisation_slug)
        lat, lon = point_at(north, east)
        drone = start_drone(
            self.directory / drone_id, drone_id, url, (lat, lon, HOME_ALT_MSL),
            time_scale=self.time_scale, agent_args=["--heartbeat-interval", "0.3"],
        )  # fmt: skip
        self.drones[drone_id] = drone
        return drone

    def wait_online(self, drone_ids: list[str], timeout: float = 40.0) -> None:
        from fleet.models import Drone

        def ready() -> bool:
            rows = Drone.objects.filter(drone_id__in=drone_ids, online=True, lat__isnull=False)
            return rows.exclude(battery_remaining__isnull=True).count() == len(drone_ids)

        if not wait_for(ready, timeout):
            raise AssertionError(f"drones not online: {drone_ids}\n{self.processes.describe()}")

    def close(self) -> None:
        for drone in self.drones.values():
            drone.stop()
        self.processes.stop()


def _point_test_process_at(settings, values: dict[str, object]) -> None:  # type: ignore[no-untyped-def]
    """The test process provisions drones and reads the outbox: same broker and Redis."""
    from workers import outbox

    for name, value in values.items():
        setattr(settings, name, value)
    outbox._sync_client = None


def _database_name() -> str:
    from django.db import connection

    return connection.settings_dict["NAME"]


@contextmanager
def mosquitto_ground(
    directory: Path,
    settings,  # type: ignore[no-untyped-def]
    *,
    redis_url: str | None = None,
    env: dict[str, str] | None = None,
    beat: bool = True,
    time_scale: float = TIME_SCALE,
    **counts: int,
) -> Iterator[ReplicatedGround]:
    """A private Mosquitto and `counts` ground processes (web=, gateways=, ingests=,
    workers=) with beat; the gateways and ingests share the drones' topics through
    `$share/...` subscriptions."""
    from workers.mosquitto import start_broker

    folder = Path(directory) / "mosquitto"
    broker = start_broker(
        folder, {"ground": GROUND_PASSWORD}, extra_config=f"pid_file {folder / 'mosquitto.pid'}\n"
    )
    redis_url = redis_url or redis_url_with_db(settings.REDIS_URL, REDIS_DB)
    ground_url = broker.url_for("ground")
    _point_test_process_at(
        settings,
        {
            "MQTT_BROKER": "mosquitto",
            "MQTT_URL": ground_url,
            "MQTT_URLS": [ground_url],
            "MOSQUITTO_DIR": str(folder),
            "MQTT_PUBLIC_HOST": "127.0.0.1",
            "MQTT_PUBLIC_PORT": broker.port,
            "REDIS_URL": redis_url,
        },
    )
    process_env = {
        **FAST_ENV,
        "MQTT_BROKER": "mosquitto",
        "MQTT_URL": ground_url,
        "MQTT_URLS": ground_url,
        "MOSQUITTO_DIR": str(folder),
        "REDIS_URL": redis_url,
        **(env or {}),
    }
    processes = ground_processes(Path(directory) / "ground", _database_name(), process_env)
    ground = ReplicatedGround(
        processes,
        Path(directory) / "drones",
        lambda drone_id, password: f"mqtt://{drone_id}:{password}@127.0.0.1:{broker.port}",
        broker=broker,
        time_scale=time_scale,
    )
    try:
        processes.add(beat=beat, **counts).start()
        yield ground
    finally:
        ground.close()
        broker.stop()
        _point_test_process_at(settings, {})


@contextmanager
def rabbitmq_ground(
    directory: Path,
    settings,  # type: ignore[no-untyped-def]
    cluster,  # type: ignore[no-untyped-def]
    *,
    redis_url: str | None = None,
    env: dict[str, str] | None = None,
    beat: bool = True,
    time_scale: float = TIME_SCALE,
    first_node: int = 1,
    **counts: int,
) -> Iterator[ReplicatedGround]:
    """The same on a RabbitCluster: drones get every node's URL (they fail over in turn,
    from `first_node` on, as every ground process does), the gateways and ingests consume
    the shared AMQP queues."""
    redis_url = redis_url or redis_url_with_db(settings.REDIS_URL, REDIS_DB)
    broker_env = cluster.settings_env(first_node)
    _point_test_process_at(
        settings,
        {
            "MQTT_BROKER": "rabbitmq",
            "MQTT_URL": broker_env["MQTT_URL"],
            "MQTT_URLS": broker_env["MQTT_URLS"].split(","),
            "AMQP_URLS": broker_env["AMQP_URLS"].split(","),
            "RABBITMQ_API_URLS": broker_env["RABBITMQ_API_URLS"].split(","),
            "REDIS_URL": redis_url,
        },
    )
    process_env = {**FAST_ENV, **broker_env, "REDIS_URL": redis_url, **(env or {})}
    processes = ground_processes(Path(directory) / "ground", _database_name(), process_env)

    def drone_url(drone_id: str, password: str) -> str:
        nodes = cluster.node_order(list(range(1, cluster.nodes + 1)), first_node)
        return ",".join(
            f"mqtt://{drone_id}:{password}@127.0.0.1:{cluster.mqtt_port(i)}" for i in nodes
        )

    ground = ReplicatedGround(
        processes, Path(directory) / "drones", drone_url, broker=cluster, time_scale=time_scale
    )
    try:
        processes.add(beat=beat, **counts).start()
        yield ground
    finally:
        ground.close()
        _point_test_process_at(settings, {})


# -- what a user does: the API through every web instance, a mission's websocket ----------


class Api:
    """The REST API with a token, each request to the next web instance in turn."""

    def __init__(self, user, urls: list[str]) -> None:  # type: ignore[no-untyped-def]
        import requests
        from rest_framework.authtoken.models import Token

        token, _ = Token.objects.get_or_create(user=user)
        self.urls = list(urls)
        self.sessions = []
        for _ in self.urls:
            session = requests.Session()
            session.headers["Authorization"] = f"Token {token.key}"
            self.sessions.append(session)
        self.calls = [0] * len(self.urls)
        self._turn = 0

    def request(self, method: str, path: str, body: dict | None = None):  # type: ignore[no-untyped-def]
        i = self._turn % len(self.urls)
        self._turn += 1
        self.calls[i] += 1
        return self.sessions[i].request(method, self.urls[i] + path, json=body, timeout=30)

    def get(self, path: str):  # type: ignore[no-untyped-def]
        return self.request("GET", path)

    def post(self, path: str, body: dict | None = None):  # type: ignore[no-untyped-def]
        return self.request("POST", path, body)


class MissionSocket:
    """`/ws/missions/<id>/` on one web instance, logged in; collects every message."""

    def __init__(self, base_url: str, mission_id: str, user) -> None:  # type: ignore[no-untyped-def]
        import threading

        from tests.support.websocket import session_cookie

        self.url = base_url.replace("http://", "ws://") + f"/ws/missions/{mission_id}/"
        self.headers = {"Cookie": session_cookie(user).decode(), "Origin": base_url}
        self.messages: list[dict] = []
        self.opened = threading.Event()
        self.closing = threading.Event()
        self.error: BaseException | None = None
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if not self.opened.wait(15):
            raise AssertionError(f"websocket {self.url} did not open: {self.error!r}")

    def _read(self) -> None:
        import json

        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        try:
            with connect(self.url, additional_headers=self.headers, open_timeout=10) as ws:
                self.opened.set()
                while not self.closing.is_set():
                    try:
                        self.messages.append(json.loads(ws.recv(timeout=0.2)))
                    except TimeoutError:
                        continue
        except ConnectionClosed:
            pass
        except Exception as exc:  # noqa: BLE001 - reported by __init__ or the assertions
            self.error = exc

    def step_completions(self) -> list[int]:
        """The accepted step completions pushed, each event once: a replay (after a
        redelivered report) carries the id of the event it repeats."""
        pushed = {
            m["id"]: m["data"]["index"]
            for m in self.messages
            if m.get("type") == "event"
            and m.get("kind") == "step"
            and m["data"].get("status") == "completed"
            and not m["data"].get("ignored")
        }
        return sorted(pushed.values())

    def close(self) -> None:
        self.closing.set()
        self._reader.join(5)


@dataclass
class MissionRun:
    """What a replacement mission left behind, and the checks that it happened once."""

    mission_id: str
    socket: MissionSocket
    failing: str
    replacing: str

    def describe(self) -> str:
        from missions.models import Mission

        mission = Mission.objects.get(pk=self.mission_id)
        steps = [
            f"{s.index}:{s.command}:{s.status}:{s.drone.drone_id if s.drone else None}"
            for s in mission.steps.order_by("index")
        ]
        events = [f"{e.kind}:{e.message}" for e in mission.events.order_by("at")]
        lateness = [
            round(e.data["received_at"] - e.data["ts"], 2)
            for e in mission.events.filter(kind="alarm")
            if e.data.get("received_at") and e.data.get("ts")
        ]
        return (
            "steps " + ", ".join(steps) + "\nevents " + "; ".join(events)
            + f"\nalarm received after (s) {lateness}"
        )  # fmt: skip

    def assert_exactly_once(self, *, duplicate_alarms: int = 1) -> None:
        from missions.models import STEP_DONE, Assignment, Event, Mission, StepStatus

        from .experiments import accepted_completions

        mission = Mission.objects.get(pk=self.mission_id)
        # (This module is not a test file: pytest does not explain its asserts, we do.)
        why = self.describe()
        assert mission.status == "completed", why
        # One decision, however many gateways, workers and alarm copies there were.
        replacements = mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT)
        assert [a.drone.drone_id for a in replacements] == [self.replacing], why
        assert mission.events.filter(data__decision="replacement").count() == 1, why
        assert mission.events.filter(data__decision="stop_failing").count() == 1, why
        # Copies of the one alarm raised: the drone's, ours (`duplicate_alarms` of them),
        # and any the broker delivered again after a fault (a gateway killed before
        # acknowledging it): the same message, recorded once (its `message_key`).
        alarms = list(
            mission.events.filter(kind=Event.Kind.ALARM).values_list("drone__drone_id", "data__ts")
        )
        assert len(alarms) == 1 and alarms[0][0] == self.failing, (duplicate_alarms, why)
        # Every step done, each completion accepted once.
        assert not mission.steps.exclude(status__in=STEP_DONE).exists(), why
        waits = mission.steps.filter(command="wait_for_flight")
        assert not waits.exclude(status=StepStatus.COMPLETED).exists(), why
        completed = set(
            mission.steps.filter(status=StepStatus.COMPLETED).values_list("index", flat=True)
        )
        # A step's own report may come after "mission completed" (a restarted gateway
        # handing over what it had queued): it is still accepted, once.
        wait_for(lambda: set(accepted_completions(mission)) >= completed, 10)
        accepted = sorted(accepted_completions(mission))
        why = self.describe()
        assert len(accepted) == len(set(accepted)), f"a step was completed twice: {why}"
        assert set(accepted) == completed, (sorted(completed - set(accepted)), why)
        flown_by = set(waits.values_list("drone__drone_id", flat=True))
        assert flown_by == {self.failing, self.replacing}, why
        # The page on one web instance saw every step's progress once, whichever gateway
        # or worker produced it.
        assert wait_for(lambda: self.socket.step_completions() == accepted, 10), (
            self.socket.step_completions(),
            accepted,
        )
        # The push of the mission's end may follow its last step's by a moment.
        assert wait_for(
            lambda: any(
                m.get("type") == "mission" and m.get("status") == "completed"
                for m in self.socket.messages
            ),
            10,
        ), self.socket.messages[-5:]


def connect_any(client, urls: str) -> None:  # type: ignore[no-untyped-def]
    """Connect a paho client to the first node of `urls` (comma-separated) that answers."""
    from urllib.parse import urlsplit

    error: OSError | None = None
    for url in urls.split(","):
        parts = urlsplit(url)
        client.username_pw_set(parts.username, parts.password)
        try:
            client.connect(parts.hostname or "127.0.0.1", parts.port or 1883)
            return
        except OSError as exc:
            error = exc
    raise AssertionError(f"no broker node answers: {error!r}")


def drone_client_id(urls: str) -> str:
    """The drone id of a drone's broker URLs (comma-separated): the client id a drone
    account without its agent connects with."""
    from urllib.parse import unquote, urlsplit

    return unquote(urlsplit(urls.split(",")[0]).username or "")


def publish_as(url: str, topic: str, message: dict) -> None:
    """Publish once with a drone's own credentials (QoS 1), as a redelivery would arrive.
    The client id is the drone id, one a drone account may use beside its agent's
    `skyhive-agent-<id>` (brokers refuse or replace any other)."""
    import json
    import threading

    import paho.mqtt.client as mqtt

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=drone_client_id(url))
    connected = threading.Event()
    client.on_connect = lambda c, u, f, rc, p: rc.is_failure or connected.set()
    connect_any(client, url)
    client.loop_start()
    try:
        assert connected.wait(5), "could not connect as the drone"
        client.publish(topic, json.dumps(message), qos=1).wait_for_publish(5)
    finally:
        client.disconnect()
        client.loop_stop()


def fly_replacement_mission(
    ground: ReplicatedGround,
    organisation_slug: str,
    api: Api,
    user,  # type: ignore[no-untyped-def]
    *,
    prefix: str = "ACME_R",
    during: Callable[[], None] | None = None,
    during_after_steps: int = 4,
    during_after_alarm: bool = False,
    duplicate_alarm: bool = True,
    timeout: float = 90.0,
) -> MissionRun:
    """Two drones; the first flies a survey, raises CRITICAL after its fourth waypoint
    (the alarm is then delivered a second time, as a QoS 1 redelivery would, unless
    `duplicate_alarm` is False), the second takes over. `during` (a fault) runs once
    `during_after_steps` steps are complete, or once the alarm is on record."""
    from missions.models import Event, Mission, StepStatus

    from .experiments import survey_with_alarm

    failing, replacing = f"{prefix}1", f"{prefix}2"
    ground.add_drone(failing, organisation_slug, north=-10)
    ground.add_drone(replacing, organisation_slug, north=-40, east=-20)
    ground.wait_online([failing, replacing])
    # CRITICAL, as the drone would raise it on a low battery: it must be replaced.
    steps, _ = survey_with_alarm("CRITICAL", 40, 20, 10, 4, message="battery")
    created = api.post("/api/v1/missions/", {"name": "replicated", "steps": steps})
    assert created.status_code == 201, created.text
    mission_id = created.json()["id"]
    socket_ = MissionSocket(api.urls[0], mission_id, user)
    started = api.post(f"/api/v1/missions/{mission_id}/start/", {"drone": failing})
    assert started.status_code == 200, started.text

    def steps_done() -> bool:
        done = StepStatus.COMPLETED
        return Mission.objects.get(pk=mission_id).steps.filter(status=done).count() >= (
            during_after_steps
        )

    def alarm_recorded() -> Event | None:
        return Event.objects.filter(mission_id=mission_id, kind="alarm").first()

    if during is not None:
        ready = alarm_recorded if during_after_alarm else steps_done
        assert wait_for(ready, timeout), ground.processes.describe()
        during()
    alarm = wait_for(alarm_recorded, timeout)
    assert alarm is not None, ground.processes.describe()
    if duplicate_alarm:
        _publish_duplicate(ground, failing, mission_id, alarm)

    def finished() -> bool:
        status = api.get(f"/api/v1/missions/{mission_id}/").json().get("status")
        return status in ("completed", "failed", "stopped")

    if not wait_for(finished, timeout, interval=0.5):
        events = list(Event.objects.filter(mission_id=mission_id).values_list("message", flat=True))
        raise AssertionError(f"mission not finished; last events {events[-15:]}")
    return MissionRun(mission_id, socket_, failing, replacing)


def _publish_duplicate(ground: ReplicatedGround, failing: str, mission_id: str, alarm) -> None:  # type: ignore[no-untyped-def]
    from .experiments import redelivered_alarm

    duplicate = redelivered_alarm(alarm, mission_id)
    publish_as(ground.drones[failing].broker_url, f"{failing}/alarms/out", duplicate)


# -- a numbered telemetry stream, to count what is stored -----------------------------------


class Telemetry:
    """A drone with no agent publishing `messages` numbered telemetry messages (QoS 1, two
    objects each, every timestamp distinct) in the background, at `rate` per second."""

    OBJECTS = ("AttitudeActual", "BaroAltitude")

    def __init__(self, drone_pk: int, url: str, topic: str, messages: int, rate: float) -> None:
        import threading

        self.drone_pk = drone_pk
        self.url = url
        self.topic = topic
        self.messages = messages
        self.rate = rate
        self.sent = 0
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._publish, daemon=True)

    @classmethod
    def start(
        cls,
        ground: ReplicatedGround,
        organisation_slug: str,
        drone_id: str,
        *,
        messages: int = 400,
        rate: float = 40.0,
    ) -> Telemetry:
        from fleet.models import Drone

        url = ground.provision(drone_id, organisation_slug)
        pk = Drone.objects.get(drone_id=drone_id).pk
        # An ingest looks up an unknown drone at most every DroneMap.after_miss (0.5 s) and
        # drops (and counts) its samples meanwhile: a drone provisioned this very moment
        # could lose its first ones. Real drones connect seconds after provisioning.
        time.sleep(1.0)
        stream = cls(pk, url, f"{drone_id}/telemetry/out", messages, rate)
        stream._thread.start()
        return stream

    @property
    def expected(self) -> int:
        return self.messages * len(self.OBJECTS)

    def _publish(self) -> None:
        import json

        import paho.mqtt.client as mqtt

        try:
            client = mqtt.Client(
                mqtt.CallbackAPIVersion.VERSION2, client_id=drone_client_id(self.url)
            )
            client.max_queued_messages_set(0)
            connect_any(client, self.url)
            client.loop_start()
            start = time.time() - 60
            infos = []
            for i in range(self.messages):
                ts = start + i * 0.01
                objects = [
                    {"name": name, "ts": ts, "fields": {"n": i, "k": k}}
                    for k, name in enumerate(self.OBJECTS)
                ]
                payload = json.dumps({"objects": objects, "ts": ts})
                infos.append(client.publish(self.topic, payload, qos=1))
                self.sent += 1
                time.sleep(1.0 / self.rate)
            for info in infos:
                info.wait_for_publish(10)
            client.disconnect()
            client.loop_stop()
        except BaseException as exc:  # noqa: BLE001 - reported by assert_stored_once
            self.error = exc

    def stored(self) -> tuple[int, int]:
        """(rows, distinct (object, ts)) stored for this drone."""
        from django.db import connection

        with connection.cursor() as cursor:
            cursor.execute(
                "SELECT count(*), count(DISTINCT (object, ts)) FROM telemetry_sample "
                "WHERE drone_id = %s",
                [self.drone_pk],
            )
            return cursor.fetchone()

    def assert_stored_once(self, timeout: float = 30.0) -> None:
        self._thread.join(timeout)
        assert self.error is None, f"publishing failed: {self.error!r}"
        assert self.sent == self.messages, f"{self.sent} of {self.messages} sent"
        wait_for(lambda: self.stored()[0] >= self.expected, timeout, interval=0.25)
        time.sleep(0.5)  # a duplicate written late would show now
        rows, distinct = self.stored()
        assert (rows, distinct) == (self.expected, self.expected), (
            f"{rows} rows, {distinct} distinct stored of {self.expected} sent"
        )

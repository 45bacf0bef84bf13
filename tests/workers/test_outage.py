"""A database or Redis outage of a minute while a drone reports a running mission and
raises a CRITICAL alarm: the gateway keeps running, acknowledges nothing it has not
stored, and after recovery every step report is stored once and the drone is replaced
once. On a ground of its own (tests/support/outage.py): the real `manage.py gateway`
and a Celery worker, with PostgreSQL and Redis that the test stops and starts."""

from __future__ import annotations

import json
import signal
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
import pytest

from runtime.processes import wait_for
from tests.support.outage import OutageGround

pytestmark = pytest.mark.e2e

OUTAGE_S = 60.0
# An unacknowledged CRITICAL alarm is sent again this often (onboard.failsafe).
ALARM_REPEAT_S = 10.0
RECOVERY_S = 120.0


@pytest.fixture(scope="module")
def ground(tmp_path_factory):  # type: ignore[no-untyped-def]
    stack = OutageGround(
        tmp_path_factory.mktemp("outage"), ("FAILING_PG", "SPARE_PG", "FAILING_RD", "SPARE_RD")
    )
    try:
        stack.start()
        stack.start_ground()
        yield stack
    finally:
        stack.stop()


class DroneLink:
    """What a drone's agent publishes on `<id>/mission/out` and `<id>/alarms/out`
    (docs/protocol.md), QoS 1 on a clean session, as onboard.mqtt does."""

    def __init__(self, url: str, drone_id: str, scene: dict) -> None:
        parts = urlsplit(url)
        self.drone_id = drone_id
        self.scene = scene
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=drone_id)
        self.client.username_pw_set(parts.username, parts.password)
        connected = threading.Event()
        self.client.on_connect = lambda *args: connected.set()
        self.client.connect(parts.hostname or "127.0.0.1", parts.port or 1883)
        self.client.loop_start()
        assert connected.wait(10)
        self.client.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def _send(self, channel: str, message: dict) -> None:
        info = self.client.publish(f"{self.drone_id}/{channel}/out", json.dumps(message), qos=1)
        info.wait_for_publish(10)

    def step(self, index: int, status: str, ts: float) -> dict:
        message = {
            "type": "step",
            "mission_id": self.scene["mission_id"],
            "assignment_id": self.scene["assignment_id"],
            "index": index,
            "command": self.scene["steps"][index]["command"],
            "status": status,
            "ts": ts,
            "position": {"lat": 40.6304, "lon": -8.6574, "alt": 10.0},
            "duration_s": None if status == "started" else 2.5,
            "result": {},
            "error": None,
        }
        self._send("mission", message)
        return message

    def resend(self, message: dict) -> None:
        """The same message again, as a broker redelivers one whose PUBACK it missed."""
        self._send("mission", message)

    def critical(self, index: int, ts: float, repeated: bool) -> None:
        again = " (repeated until acknowledged)" if repeated else ""
        self._send(
            "alarms",
            {
                "type": "alarm",
                "level": "CRITICAL",
                "message": f"battery below 25 %{again}",
                "ts": ts,
                "position": {"lat": 40.6305, "lon": -8.6573, "alt": 10.0},
                "mission_id": self.scene["mission_id"],
                "assignment_id": self.scene["assignment_id"],
                "index": index,
                "sensor": None,
                "value": None,
            },
        )

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def _step_events(ground: OutageGround, mission_id: str) -> Counter:
    rows = ground.query(
        "SELECT (data->>'index')::int, data->>'status' FROM missions_event "
        "WHERE mission_id = %s AND kind = 'step'",
        mission_id,
    )
    return Counter(rows)


def _count(ground: OutageGround, sql: str, *params: object) -> int:
    return ground.query(sql, *params)[0][0]


def _replacements(ground: OutageGround, assignment_id: str) -> int:
    return _count(
        ground, "SELECT count(*) FROM missions_assignment WHERE replaces_id = %s", assignment_id
    )


def _alarms(ground: OutageGround, mission_id: str) -> int:
    return _count(
        ground,
        "SELECT count(*) FROM missions_event WHERE mission_id = %s AND kind = 'alarm'",
        mission_id,
    )


def _fly_through(
    ground: OutageGround,
    drone: DroneLink,
    during: Callable[[float], None] = lambda elapsed: None,
) -> tuple[set, int]:
    """Report steps 1 and 2 and raise the CRITICAL alarm (repeated while unanswered)
    for OUTAGE_S; `during(elapsed)` is called about every second. The step reports
    and the number of alarms sent."""
    began = time.monotonic()
    now = time.time()
    sent = [(0, "started"), (0, "completed"), (1, "started"), (1, "completed"), (2, "started")]
    completed = None
    for i, (index, status) in enumerate(sent[2:]):
        message = drone.step(index, status, now + i)
        completed = message if status == "completed" else completed
        time.sleep(0.3)
    assert completed is not None
    drone.resend(completed)
    alarms = 0
    next_alarm = 0.0
    while (elapsed := time.monotonic() - began) < OUTAGE_S:
        if elapsed >= next_alarm:
            drone.critical(2, time.time(), repeated=alarms > 0)
            alarms += 1
            next_alarm += ALARM_REPEAT_S
        during(elapsed)
        time.sleep(1.0)
    return set(sent), alarms


def _recovered(ground: OutageGround, scene: dict, sent: set, alarms: int) -> None:
    """Every step report stored once, every alarm recorded once, one replacement."""

    def done() -> bool:
        return (
            set(_step_events(ground, scene["mission_id"])) == sent
            and _replacements(ground, scene["assignment_id"]) == 1
            and _alarms(ground, scene["mission_id"]) == alarms
        )

    assert wait_for(done, RECOVERY_S, interval=0.5), (
        _step_events(ground, scene["mission_id"]),
        _replacements(ground, scene["assignment_id"]),
        _alarms(ground, scene["mission_id"]),
        ground.gateway.output()[-3000:] if ground.gateway else "",
    )
    time.sleep(3)  # anything retried or redelivered late would land now
    events = _step_events(ground, scene["mission_id"])
    assert set(events) == sent and set(events.values()) == {1}, events
    assert _replacements(ground, scene["assignment_id"]) == 1
    assert _alarms(ground, scene["mission_id"]) == alarms


def _before_the_outage(ground: OutageGround, drone: DroneLink, scene: dict) -> None:
    now = time.time() - 10
    drone.step(0, "started", now)
    drone.step(0, "completed", now + 1)
    assert wait_for(lambda: len(_step_events(ground, scene["mission_id"])) == 2, 20)


def test_postgres_down_for_a_minute_and_the_gateway_killed_meanwhile_loses_nothing(ground):
    scene = ground.scene("FAILING_PG", "SPARE_PG")
    drone = DroneLink(ground.drone_url("FAILING_PG"), "FAILING_PG", scene)
    gateway = ground.gateway
    assert gateway is not None
    try:
        _before_the_outage(ground, drone, scene)
        assert ground.postgres is not None
        ground.postgres.stop()
        assert not ground.reachable()
        killed: list[float] = []

        def during(elapsed: float) -> None:
            # Halfway, the gateway is killed with messages in hand, and started again:
            # what it had not stored was never acknowledged, so the broker keeps it for
            # its persistent session.
            if elapsed >= OUTAGE_S / 2 and not killed:
                assert gateway.alive, gateway.output()[-3000:]
                gateway.kill(signal.SIGKILL)
                killed.append(elapsed)
                gateway.start().wait_ready(60)

        sent, alarms = _fly_through(ground, drone, during)
        assert killed and gateway.alive, gateway.output()[-3000:]
        ground.postgres.start()
        _recovered(ground, scene, sent, alarms)
        assert gateway.alive
    finally:
        drone.close()


def test_redis_down_for_a_minute_loses_no_alarm_and_queues_one_replacement(ground):
    scene = ground.scene("FAILING_RD", "SPARE_RD")
    drone = DroneLink(ground.drone_url("FAILING_RD"), "FAILING_RD", scene)
    gateway = ground.gateway
    assert gateway is not None
    try:
        _before_the_outage(ground, drone, scene)
        ground.stop_redis()
        sent, alarms = _fly_through(ground, drone)
        # Step reports need only the database: stored during the outage. The alarm's
        # replacement task needs Redis: nothing was decided yet.
        assert set(_step_events(ground, scene["mission_id"])) == sent
        assert _replacements(ground, scene["assignment_id"]) == 0
        assert gateway.alive, gateway.output()[-3000:]
        ground.start_redis()
        _recovered(ground, scene, sent, alarms)
        assert gateway.alive
    finally:
        drone.close()

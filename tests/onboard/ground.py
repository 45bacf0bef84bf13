"""A stand-in for the ground side in end-to-end tests: an MQTT client that sends requests
to a drone and collects everything the drone publishes, in order."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import paho.mqtt.client as paho
from paho.mqtt.enums import CallbackAPIVersion

from onboard import protocol

REPO_ROOT = Path(__file__).resolve().parents[2]


class Ground:
    def __init__(
        self,
        port: int,
        drone_id: str,
        *,
        user: str = "ground",
        password: str = "pw",
        client_id: str = "test-ground",
    ) -> None:
        self.drone_id = drone_id
        self.messages: list[tuple[str, dict]] = []
        self._cond = threading.Condition()
        # A persistent session: with broker persistence on, a restart keeps our inbox.
        self.client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            clean_session=False,
            protocol=paho.MQTTv311,
        )
        self.client.username_pw_set(user, password)
        self.client.reconnect_delay_set(0.1, 1.0)
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self._subscribed = threading.Event()
        self.client.connect("127.0.0.1", port, keepalive=10)
        self.client.loop_start()
        assert self._subscribed.wait(5), "ground client could not subscribe"

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:  # noqa: ANN001
        client.subscribe(f"{self.drone_id}/+/out", qos=1)
        self._subscribed.set()

    def _on_message(self, client, userdata, message) -> None:  # noqa: ANN001
        try:
            payload = json.loads(message.payload)
        except ValueError:
            payload = {"undecodable": True}
        with self._cond:
            self.messages.append((message.topic, payload))
            self._cond.notify_all()

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()

    def on(self, channel: str) -> list[dict]:
        topic = f"{self.drone_id}/{channel}/out"
        with self._cond:
            return [m for t, m in self.messages if t == topic]

    def wait_for(self, channel: str, predicate, timeout: float = 30.0) -> dict:
        topic = f"{self.drone_id}/{channel}/out"
        deadline = time.monotonic() + timeout
        seen = 0
        with self._cond:
            while True:
                for t, m in self.messages[seen:]:
                    if t == topic and predicate(m):
                        return m
                seen = len(self.messages)
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(
                        f"nothing on {topic} matched within {timeout} s; "
                        f"last: {self.on(channel)[-3:]}"
                    )
                self._cond.wait(left)

    def send(self, channel: str, message: dict) -> None:
        info = self.client.publish(f"{self.drone_id}/{channel}/in", json.dumps(message), qos=1)
        info.wait_for_publish(5)

    def command(self, command: str, timeout: float = 30.0, **params) -> dict:
        request_id = protocol.new_request_id()
        self.send(
            "control",
            {"request_id": request_id, "command": command, "params": params, "ts": time.time()},
        )
        return self.wait_for("control", lambda m: m.get("request_id") == request_id, timeout)


def start_agent(
    tmp_path: Path,
    *,
    drone_id: str,
    link: str,
    broker_url: str,
    arming_line: Path,
    time_scale: float,
    extra: list[str] = (),
) -> subprocess.Popen:
    """`python -m onboard` as a real process, its log in tmp_path/agent.log."""
    gear = tmp_path / "gear"
    if not gear.exists():
        gear.mkdir()
        for name in ("specs.json", "sensors.json"):
            (gear / name).write_text((REPO_ROOT / "onboard" / "gear_example" / name).read_text())
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    args = [
        sys.executable,
        "-m",
        "onboard",
        "--drone-id",
        drone_id,
        "--link",
        link,
        "--broker",
        broker_url,
        "--arming",
        f"sim-line:{arming_line}",
        "--gear-dir",
        str(gear),
        "--log-dir",
        str(tmp_path / "logs"),
        "--time-scale",
        str(time_scale),
        "--heartbeat-interval",
        "0.5",
        *extra,
    ]
    log = open(tmp_path / "agent.log", "ab")  # noqa: SIM115
    try:
        return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=log, cwd=REPO_ROOT, env=env)
    finally:
        log.close()


def wait_until(predicate, timeout: float, interval: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())

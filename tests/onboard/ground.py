"""A stand-in for the ground side in end-to-end tests: an MQTT client that sends requests
to a drone and collects everything the drone publishes, in order."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import paho.mqtt.client as paho
from paho.mqtt.enums import CallbackAPIVersion

from firmware.sim.fleet import agent_process, copy_gear
from onboard import protocol
from runtime.processes import Supervised


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
    extra: list[str] = (),  # type: ignore[assignment]
) -> Supervised:
    """`python -m onboard` as a real process for a simulator the test started itself, its
    folder tmp_path (gear, logs, agent.log)."""
    copy_gear(tmp_path)
    return agent_process(
        drone_id,
        tmp_path,
        link,
        broker_url,
        arming_line=arming_line,
        time_scale=time_scale,
        extra=["--heartbeat-interval", "0.5", *extra],
    ).start()

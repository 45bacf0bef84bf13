"""Helpers for the telemetry tests: realistic drone messages, a publisher, waiting."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt


def drone_messages(start: float, seconds: float, rate_scale: float = 1.0) -> Iterator[dict]:
    """What an agent sends: batches every 100 ms of the dRonin objects at their rates."""
    step = 0.1
    n = round(seconds / step)
    for i in range(n):
        t = start + i * step
        objects = [
            {
                "name": "AttitudeActual",
                "ts": t,
                "fields": {
                    "q1": 1.0,
                    "q2": 0.0,
                    "q3": 0.0,
                    "q4": 0.0,
                    "Roll": 5 * math.sin(t),
                    "Pitch": 3 * math.cos(t),
                    "Yaw": (t * 10) % 360,
                },
            },
        ]
        if i % 10 == 0:
            objects += [
                {
                    "name": "BaroAltitude",
                    "ts": t,
                    "fields": {
                        "Altitude": 40 + math.sin(t / 10),
                        "Temperature": 21.5,
                        "Pressure": 100.8,
                    },
                },
                {
                    "name": "FlightBatteryState",
                    "ts": t,
                    "fields": {
                        "Voltage": 16.4 - i * 1e-4,
                        "Current": 12.0,
                        "ConsumedEnergy": i * 0.5,
                        "DetectedCellCount": 4,
                    },
                },
                {
                    "name": "SystemStats",
                    "ts": t,
                    "fields": {"CPULoad": 40 + i % 7, "CPUTemp": 45, "HeapRemaining": 12000},
                },
                {
                    "name": "Accels",
                    "ts": t,
                    "fields": {"x": 0.1, "y": -0.2, "z": -9.8, "temperature": 30.0},
                },
                {
                    "name": "Gyros",
                    "ts": t,
                    "fields": {"x": 0.01, "y": 0.0, "z": 0.3, "temperature": 30.0},
                },
                {
                    "name": "FlightStatus",
                    "ts": t,
                    "fields": {
                        "Armed": "Armed",
                        "FlightMode": "PathPlanner",
                        "ControlSource": "Tablet",
                    },
                },
                {
                    "name": "PathDesired",
                    "ts": t,
                    "fields": {
                        "Start": [0.0, 0.0, -10.0],
                        "End": [20.0, 5.0, -10.0],
                        "Mode": "Endpoint",
                    },
                },
            ]
        if i % 50 == 0:
            objects.append(
                {
                    "name": "FlightTelemetryStats",
                    "ts": t,
                    "fields": {
                        "TxDataRate": 2100.0,
                        "RxDataRate": 180.0,
                        "TxFailures": 0,
                        "RxFailures": 0,
                        "TxRetries": 0,
                        "Status": "Connected",
                    },
                }
            )
        if i % 20 == 0:
            objects.append(
                {
                    "name": "GPSPosition",
                    "ts": t,
                    "fields": {
                        "Latitude": 406303000 + i,
                        "Longitude": -86575000,
                        "Altitude": 12.0,
                        "Status": "Fix3D",
                        "Satellites": 11,
                        "PDOP": 1.2,
                    },
                }
            )
        yield {"ts": t, "objects": objects}


class Publisher:
    """A paho client publishing as a given user (the ground may publish anywhere)."""

    def __init__(self, url: str, client_id: str = "") -> None:
        parts = urlsplit(url)
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id)
        self.client.username_pw_set(parts.username, parts.password)
        self.client.max_inflight_messages_set(1000)
        self.client.connect(parts.hostname, parts.port)
        self.client.loop_start()

    def publish(self, topic: str, payload: bytes | str | dict, qos: int = 1) -> None:
        if isinstance(payload, dict):
            payload = json.dumps(payload)
        info = self.client.publish(topic, payload, qos=qos)
        info.wait_for_publish(10)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()

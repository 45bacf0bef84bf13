"""The ingest's MQTT reader against a plain paho client: messages/s one subscriber takes in.

    .venv/bin/python -m bench.bench_mqtt_reader

Needs no service of the test profile: a private Mosquitto on a free loopback port
(anonymous, no persistence, no per-client queue limit so that no QoS 0 message is
dropped while a subscriber lags). A publisher process writes MESSAGES QoS 0 PUBLISH
packets of a ~200-byte telemetry message straight to its socket, in batches, as fast as the
broker takes them; 100 drones' topics in turn. The subscriber under test runs in this
process on the ingest's shared subscription, and its on_message only counts.

Key:
- telemetry.mqtt_reader_msgs_per_s: messages/s the hand-written reader
  (workers/broker/mqtt_reader.py, `Subscriber`) delivers, from the publisher's first
  write to the last message delivered; the best of ROUNDS rounds. Baseline: one paho-mqtt
  2.x client (its own network thread, `loop_start`) on the same subscription with the
  same counting on_message, in rounds alternating with the reader's.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import shutil
import socket
import tempfile
import threading
import time
from collections.abc import Callable
from multiprocessing.synchronize import Event as ProcessEvent
from pathlib import Path

from bench.common import record
from runtime.mqttwire import connect_packet, publish_packet
from runtime.processes import Supervised, free_port
from workers.broker import share_filter
from workers.broker.mqtt_reader import Subscriber

MESSAGES = int(os.environ.get("BENCH_MQTT_READER_MESSAGES", 200_000))
ROUNDS = int(os.environ.get("BENCH_MQTT_READER_ROUNDS", 3))
DRONES = 100
BATCH = 1000  # packets per socket write
# A round ends when the subscriber has had nothing new for this long (messages lost).
STALL_S = 5.0
MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
TOPIC_FILTER = share_filter("bench", "telemetry")


def telemetry_payload() -> bytes:
    """One AttitudeActual sample as a drone sends it: about 200 bytes of JSON."""
    ts = 1_700_000_000.123456
    fields = {"q1": 0.9987, "q2": 0.0123, "q3": -0.0456, "q4": 0.0211}
    fields |= {"Roll": 1.53, "Pitch": -0.57, "Yaw": 87.04}
    sample = {"ts": ts, "objects": [{"name": "AttitudeActual", "ts": ts, "fields": fields}]}
    return json.dumps(sample).encode()


def start_mosquitto(directory: Path) -> Supervised:
    """A throw-away anonymous broker on a free port, accepting connections within 10 s."""
    port = free_port()
    lines = [
        f"listener {port} 127.0.0.1",
        "allow_anonymous true",
        "set_tcp_nodelay true",
        "persistence false",
        "max_queued_messages 0",
    ]
    if os.geteuid() == 0:
        lines.append("user root")
    conf = directory / "mosquitto.conf"
    conf.write_text("\n".join(lines) + "\n")
    broker = Supervised("mosquitto", [MOSQUITTO, "-c", str(conf)], port=port)
    return broker.start().wait_ready(10)


def publish(port: int, count: int, ready: ProcessEvent, go: ProcessEvent) -> None:
    """Connect, say ready, then write `count` QoS 0 PUBLISH packets once told to go."""
    sock = socket.create_connection(("127.0.0.1", port))
    sock.sendall(connect_packet("bench-publisher", None, None, keepalive=60, clean_session=True))
    if sock.recv(4)[:2] != b"\x20\x02":
        raise RuntimeError("the broker refused the publisher")
    payload = telemetry_payload()
    packets = [publish_packet(f"drone-{i % DRONES}/telemetry/out", payload) for i in range(BATCH)]
    batch = b"".join(packets)
    ready.set()
    go.wait()
    for _ in range(count // BATCH):
        sock.sendall(batch)
    sock.sendall(b"".join(packets[: count % BATCH]))
    sock.sendall(b"\xe0\x00")  # DISCONNECT
    sock.close()


class Counter:
    """The on_message of both contenders: count, and say when the last one came."""

    def __init__(self, target: int) -> None:
        self.seen = 0
        self.target = target
        self.done = threading.Event()

    def __call__(self, *message: object) -> None:
        self.seen += 1
        if self.seen == self.target:
            self.done.set()


def reader_subscriber(port: int, counter: Counter) -> Callable[[], None]:
    """Start the hand-written reader, subscribed; returns its stop."""
    reader = Subscriber(f"mqtt://127.0.0.1:{port}", "bench-reader", TOPIC_FILTER, counter)
    reader.start()
    if not reader.subscribed.wait(10):
        raise RuntimeError("the reader did not subscribe")
    return reader.stop


def paho_subscriber(port: int, counter: Counter) -> Callable[[], None]:
    """Start a plain paho client, subscribed; returns its stop."""
    import paho.mqtt.client as mqtt

    subscribed = threading.Event()
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="bench-paho")
    client.on_connect = lambda c, userdata, flags, code, props: c.subscribe(TOPIC_FILTER, qos=1)
    client.on_subscribe = lambda c, userdata, mid, codes, props: subscribed.set()
    client.on_message = counter
    client.connect("127.0.0.1", port)
    client.loop_start()
    if not subscribed.wait(10):
        raise RuntimeError("the paho client did not subscribe")

    def stop() -> None:
        client.disconnect()
        client.loop_stop()

    return stop


def run_round(port: int, start: Callable[[int, Counter], Callable[[], None]]) -> tuple[float, int]:
    """(messages/s from the first write to the last delivery, messages lost) for one subscriber."""
    ctx = mp.get_context("spawn")
    ready, go = ctx.Event(), ctx.Event()
    publisher = ctx.Process(target=publish, args=(port, MESSAGES, ready, go))
    publisher.start()
    counter = Counter(MESSAGES)
    stop = start(port, counter)
    try:
        if not ready.wait(30):
            raise RuntimeError("the publisher did not connect")
        started = time.perf_counter()
        go.set()
        last_seen, last_progress = 0, started
        while not counter.done.wait(0.5):
            if counter.seen != last_seen:
                last_seen, last_progress = counter.seen, time.perf_counter()
            elif time.perf_counter() - last_progress > STALL_S:
                break
        ended = time.perf_counter() if counter.done.is_set() else last_progress
    finally:
        stop()
        publisher.join(30)
    return counter.seen / (ended - started), MESSAGES - counter.seen


def main() -> None:
    rates: dict[str, list[float]] = {"reader": [], "paho": []}
    lost = 0
    with tempfile.TemporaryDirectory(prefix="bench-mqtt-reader-") as tmp:
        broker = start_mosquitto(Path(tmp))
        port = broker.port
        assert port is not None
        try:
            for _ in range(ROUNDS):
                for name, start in (("reader", reader_subscriber), ("paho", paho_subscriber)):
                    rate, missing = run_round(port, start)
                    rates[name].append(rate)
                    lost += missing
                    print(f"{name}: {rate:,.0f} messages/s ({missing} lost)", flush=True)
        finally:
            broker.stop(10)
    record(
        "telemetry.mqtt_reader_msgs_per_s",
        value=max(rates["reader"]),
        unit="messages/s",
        baseline_name="one paho-mqtt 2.x client, on_message only counting",
        baseline_value=max(rates["paho"]),
        higher_is_better=True,
        goal="well above paho (else replace the reader by paho); 1 000 drones at 10 Hz = 10 000/s",
        messages=MESSAGES,
        payload_bytes=len(telemetry_payload()),
        rounds={name: [round(rate) for rate in values] for name, values in rates.items()},
        lost=lost,
    )


if __name__ == "__main__":
    main()

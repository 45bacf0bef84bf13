"""The services' protective settings, on real processes: Mosquitto forwards no payload
larger than the gateway keeps, and `make run`'s Redis keeps an append-only file."""

import subprocess
import uuid
from pathlib import Path

import pytest
import redis

from runtime.processes import free_port, wait_for
from tests.fleet.conftest import mqtt_client
from workers.dispatch import MAX_PAYLOAD_BYTES
from workers.mosquitto import MESSAGE_SIZE_LIMIT, start_broker

ROOT = Path(__file__).resolve().parents[2]
SERVICES = str(ROOT / "scripts" / "services.sh")


def test_the_limit_is_the_largest_payload_the_gateway_keeps():
    assert MESSAGE_SIZE_LIMIT == MAX_PAYLOAD_BYTES["pictures"] == 16 * 1024 * 1024


def assert_oversize_is_dropped(url: str) -> None:
    """Publish 17 MiB, then a marker, on one connection: the marker arrives, the big one
    (which would come first) never does."""
    topic = f"D_{uuid.uuid4().hex[:6]}/pictures/out"
    received: list[int] = []
    subscriber = mqtt_client(url)
    publisher = mqtt_client(url)
    try:
        subscriber.on_message = lambda c, u, message: received.append(len(message.payload))
        subscriber.subscribe(topic, qos=1)
        wait_for(lambda: subscriber.is_connected(), timeout=5)
        publisher.publish(topic, b"x" * (17 * 1024 * 1024), qos=1).wait_for_publish(30)
        publisher.publish(topic, b"marker", qos=1).wait_for_publish(10)
        assert wait_for(lambda: len(b"marker") in received, timeout=15), received
        assert received == [len(b"marker")]
        publisher.publish(topic, b"y" * (1024 * 1024), qos=1).wait_for_publish(10)
        assert wait_for(lambda: 1024 * 1024 in received, timeout=15), received
    finally:
        for client in (subscriber, publisher):
            client.disconnect()
            client.loop_stop()


def test_a_private_broker_drops_a_payload_over_the_limit(tmp_path):
    broker = start_broker(tmp_path / "mosquitto", {"ground": uuid.uuid4().hex})
    try:
        assert_oversize_is_dropped(broker.url_for("ground"))
    finally:
        broker.stop()


@pytest.fixture
def run_services(tmp_path):
    """services.sh's Redis and Mosquitto of the `make run` profile, in a folder and on
    ports of their own."""
    env = {
        "PATH": "/usr/sbin:/usr/bin:/bin",
        "DATA_DIR": str(tmp_path / "run"),
        "REDIS_PORT": str(free_port()),
        "MQTT_PORT": str(free_port()),
    }
    try:
        for action in ("redis-start", "mosquitto-start"):
            subprocess.run([SERVICES, action, "run"], env=env, check=True, timeout=60)
        yield env
    finally:
        for action in ("mosquitto-stop", "redis-stop"):
            subprocess.run([SERVICES, action, "run"], env=env, timeout=60)


def secret(env: dict[str, str], name: str) -> str:
    return (Path(env["DATA_DIR"]) / "secrets" / name).read_text()


def test_the_run_profiles_redis_appends_and_mosquitto_drops_oversize(run_services):
    env = run_services
    client = redis.Redis(port=int(env["REDIS_PORT"]), password=secret(env, "redis_password"))
    assert client.config_get("appendonly") == {"appendonly": "yes"}
    client.close()
    mqtt_url = f"mqtt://ground:{secret(env, 'mqtt_ground_password')}@127.0.0.1:{env['MQTT_PORT']}"
    assert_oversize_is_dropped(mqtt_url)

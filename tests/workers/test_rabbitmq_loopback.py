"""A local RabbitMQ profile (scripts/rabbitmq.sh) listens on loopback only, epmd and the
Erlang distribution port included, and forwards no MQTT message larger than Mosquitto
does (16 MiB)."""

from __future__ import annotations

import ipaddress
import os
import threading
from pathlib import Path

import pytest

from onboard.mqtt import MqttLink
from runtime.processes import wait_for
from tests.support.mqtt_check import round_trip
from tests.support.paths import ROOT
from tests.support.rabbitmq import RabbitCluster, available

pytestmark = pytest.mark.skipif(not available(), reason="rabbitmq-server is not installed")

MESSAGE_LIMIT = 16 * 1024 * 1024


def listening(pid: int | None = None) -> list[tuple[str, int]]:
    """(address, port) of every listening TCP socket, or of those of process `pid`."""
    inodes = None
    if pid is not None:
        fd_dir = Path(f"/proc/{pid}/fd")
        links = [os.readlink(fd) for fd in fd_dir.iterdir() if fd.is_symlink()]
        inodes = {link[8:-1] for link in links if link.startswith("socket:[")}
    found = []
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if state != "0A" or (inodes is not None and inode not in inodes):  # 0A: LISTEN
                continue
            address, port = local.split(":")
            raw = bytes.fromhex(address)
            # /proc prints each 32-bit word of the address in host (little-endian) order.
            words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
            found.append((str(ipaddress.ip_address(words[: width // 2])), int(port, 16)))
    return found


@pytest.fixture
def node(rabbit_cluster: RabbitCluster) -> RabbitCluster:
    """The session's cluster, started by scripts/rabbitmq.sh as any local profile is."""
    return rabbit_cluster


def loopback(address: str) -> bool:
    return ipaddress.ip_address(address).is_loopback


def node_pid(cluster: RabbitCluster) -> int:
    pid_file = ROOT / ".data" / cluster.profile / "rabbitmq" / "1" / "pid"
    return int(pid_file.read_text().strip())


def test_every_port_of_the_node_and_its_epmd_is_on_loopback(node):
    epmd_port = node.port_base + 30
    dist_port = node.port_base + 31
    ports = listening(node_pid(node))
    assert {port for _, port in ports} >= {node.mqtt_port(1), node.amqp_port(1), dist_port}
    assert all(loopback(address) for address, _ in ports), ports
    # epmd binds ERL_EPMD_ADDRESS and, always, the IPv6 loopback too.
    epmd = [entry for entry in listening() if entry[1] == epmd_port]
    assert epmd and all(loopback(address) for address, _ in epmd), epmd


def test_an_mqtt_message_over_the_limit_is_not_forwarded(node):
    url = node.mqtt_urls[0]
    assert round_trip(url, "DRONE_R/telemetry/out")  # small ones pass
    received: list[int] = []
    got = threading.Event()

    def on_message(topic: str, payload: bytes) -> None:
        received.append(len(payload))
        got.set()

    listener = MqttLink(url, client_id="big-listener", subscriptions=["DRONE_R/picture/out"],
                        on_message=on_message)  # fmt: skip
    sender = MqttLink(url, client_id="big-sender", subscriptions=[], on_message=lambda t, p: None)
    listener.start()
    sender.start()
    try:
        assert listener.wait_connected(20) and sender.wait_connected(20)
        sender.publish("DRONE_R/picture/out", b"x" * (MESSAGE_LIMIT + 1024))
        assert not got.wait(5), received
        # A new client: the refused one's session would offer the big message again.
        sender.stop()
        sender = MqttLink(
            url, client_id="fit-sender", subscriptions=[], on_message=lambda t, p: None
        )
        sender.start()
        assert sender.wait_connected(20)
        sender.publish("DRONE_R/picture/out", b"x" * (MESSAGE_LIMIT - 64 * 1024))
        assert wait_for(lambda: bool(received), 30)
        assert received == [MESSAGE_LIMIT - 64 * 1024]
    finally:
        sender.stop()
        listener.stop()

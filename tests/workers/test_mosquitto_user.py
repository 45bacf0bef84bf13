"""Mosquitto started as root runs as an unprivileged user, and still reads the password
file and ACL that provisioning rewrites as root (the shared broker of scripts/services.sh
and the test harness workers/mosquitto.py)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from runtime.processes import free_port, wait_for
from tests.support.mqtt_check import round_trip
from tests.support.paths import ROOT
from workers.broker.credentials import MosquittoBackend, stored_hash
from workers.mosquitto import start_broker

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="privileges are dropped only by root")

SERVICES = str(ROOT / "scripts" / "services.sh")


def uids(pid: int) -> list[int]:
    """Real, effective, saved and filesystem uid of a process (/proc/<pid>/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("Uid:"):
            return [int(x) for x in line.split()[1:]]
    raise AssertionError(f"no Uid line for {pid}")


def test_the_harness_broker_drops_root_and_reads_files_provisioning_rewrites(tmp_path):
    broker = start_broker(tmp_path / "mq", {"ground": "ground-pw"},
                          extra_config=f"pid_file {tmp_path / 'mq' / 'mosquitto.pid'}\n")  # fmt: skip
    try:
        assert 0 not in uids(broker.process.pid)
        assert round_trip(broker.url_for("ground"), "DRONE_X/telemetry/out")
        # Provisioning (as root) rewrites passwd and acl and sends SIGHUP; the broker, no
        # longer root, must still read them, or every drone would be locked out.
        MosquittoBackend(broker.directory, lambda: []).sync([("DRONE_X", stored_hash("drone-pw"))])
        drone = f"mqtt://DRONE_X:drone-pw@127.0.0.1:{broker.port}"
        ground = broker.url_for("ground")
        assert wait_for(lambda: round_trip(ground, "DRONE_X/telemetry/out", drone), 20), (
            broker.log.read_text()[-2000:]
        )
        assert round_trip(drone, "DRONE_X/command/in", ground)
    finally:
        broker.stop()


def test_the_shared_broker_of_the_services_script_drops_root(tmp_path):
    # Both listeners on ports free now (the drones' would otherwise be the ground's + 1000,
    # which another process may hold).
    env = dict(os.environ, DATA_DIR=str(tmp_path / "data"), TEST_MQTT_PORT=str(free_port()),
               TEST_MQTT_DRONE_PORT=str(free_port()))  # fmt: skip
    subprocess.run([SERVICES, "mosquitto-start", "test"], env=env, check=True, timeout=60)
    directory = tmp_path / "data" / "mosquitto"
    try:
        pid = int((directory / "mosquitto.pid").read_text())
        assert 0 not in uids(pid)
        assert "user mosquitto" in (directory / "mosquitto.conf").read_text()
        password = (tmp_path / "data" / "secrets" / "mqtt_ground_password").read_text()
        url = f"mqtt://ground:{password}@127.0.0.1:{env['TEST_MQTT_PORT']}"
        assert round_trip(url, "x/y/z")
    finally:
        subprocess.run([SERVICES, "mosquitto-stop", "test"], env=env, timeout=60)

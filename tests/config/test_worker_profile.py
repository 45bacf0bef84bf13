"""A parallel test worker's service script calls find that worker's own services, whatever
ports the environment carries for `make run` (the Makefile exports MQTT_PORT)."""

import os
import subprocess
import sys

from config.env import SERVICE_PORTS, data_env_values, pin_test_ports
from tests.support.paths import ROOT


def test_the_ports_come_from_the_profile_file_not_the_environment(tmp_path, monkeypatch):
    profile = tmp_path / "env"
    profile.write_text(
        "# written by services.sh\nPG_PORT=54331\nREDIS_PORT=63793\nMQTT_PORT=18833\n"
    )
    monkeypatch.setenv("MQTT_PORT", "1883")  # what `make` exports for `make run`
    for name in SERVICE_PORTS:
        monkeypatch.delenv(f"TEST_{name}", raising=False)
    pin_test_ports(profile)
    assert os.environ["TEST_MQTT_PORT"] == "18833"
    assert os.environ["TEST_REDIS_PORT"] == "63793"
    assert os.environ["TEST_PG_PORT"] == "54331"


def test_a_missing_profile_file_pins_nothing(tmp_path, monkeypatch):
    monkeypatch.delenv("TEST_MQTT_PORT", raising=False)
    assert data_env_values(tmp_path / "none") == {}
    pin_test_ports(tmp_path / "none")
    assert "TEST_MQTT_PORT" not in os.environ


def test_a_worker_started_by_make_test_pins_its_own_mqtt_port():
    """The worker's settings, in a process with `make`'s environment."""
    worker = os.environ.get("PYTEST_XDIST_WORKER") or "gw0"
    own = data_env_values(ROOT / ".data" / f"test-{worker}" / "env").get("MQTT_PORT")
    if own is None:  # a serial run: no worker profile to compare with
        own = "absent"
    env = {**os.environ, "PYTEST_XDIST_WORKER": worker, "MQTT_PORT": "1883"}
    env.pop("TEST_PROFILE_DIR", None)
    done = subprocess.run(
        [sys.executable, "-c", "import config.settings.test, os; print(os.environ.get('TEST_MQTT_PORT', 'absent'))"],
        env=env, cwd=ROOT, capture_output=True, text=True, timeout=60, check=True,
    )  # fmt: skip
    assert done.stdout.strip() == own

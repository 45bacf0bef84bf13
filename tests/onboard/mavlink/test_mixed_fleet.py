"""`FC_MIX=uavtalk,mavlink`: the fleet launcher gives drones both protocols in turn, and
the ground commands each the same way."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from runtime.processes import REPO_ROOT, python_env, stop_process
from tests.onboard.ground import Ground
from workers.mosquitto import start_broker

from .conftest import HOME, TIME_SCALE

pytestmark = pytest.mark.e2e


def test_the_launcher_mixes_uavtalk_and_mavlink_drones_that_fly_alike(tmp_path: Path):
    users = {"ground": "pw", "MIX_1": "one", "MIX_2": "two", "MIX_3": "three"}
    broker = start_broker(tmp_path / "broker", users)
    creds = {d: {"username": d, "password": users[d]} for d in ("MIX_1", "MIX_2", "MIX_3")}
    (tmp_path / "creds.json").write_text(json.dumps(creds))
    launcher = subprocess.Popen(
        [
            sys.executable, "-m", "firmware.sim.fleet",
            "--count", "3",
            "--home", f"{HOME[0]},{HOME[1]}",
            "--credentials-file", str(tmp_path / "creds.json"),
            "--broker-url", f"mqtt://127.0.0.1:{broker.port}",
            "--time-scale", str(TIME_SCALE),
            "--workdir", str(tmp_path / "fleet"),
            "--", "--heartbeat-interval", "0.5",
        ],
        cwd=REPO_ROOT,
        env=python_env(FC_MIX="uavtalk,mavlink"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    grounds = {d: Ground(broker.port, d, client_id=f"g-{d}") for d in creds}
    try:
        beats = {
            d: g.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], 30)
            for d, g in grounds.items()
        }
        assert {d: b["fc"]["protocol"] for d, b in beats.items()} == {
            "MIX_1": "uavtalk",
            "MIX_2": "mavlink",
            "MIX_3": "uavtalk",
        }
        for drone in ("MIX_1", "MIX_2"):
            ground = grounds[drone]
            assert ground.command("arm")["ok"], drone
            assert ground.command("takeoff", altitude=6)["ok"], drone
            ground.wait_for(
                "heartbeats", lambda m: m["airborne"] and m["position"]["alt"] > 5.5, 15
            )
    finally:
        for g in grounds.values():
            g.close()
        assert stop_process(launcher, timeout=20) == 0, launcher.stderr.read()
        broker.stop()
    lines = [line for line in launcher.stdout.read().splitlines() if line.startswith("drone:")]
    assert [line.split()[2] for line in lines] == ["fc=uavtalk", "fc=mavlink", "fc=uavtalk"]

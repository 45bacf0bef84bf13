"""The onboard agent arms and disarms a simulated dRonin board through UAVTalkReceiver
channels end to end (real agent process, private Mosquitto, plain MQTT ground), on a
board set up for an arming switch in dRonin's simulation scale and on one set up for the
yaw-right stick gesture."""

from __future__ import annotations

from pathlib import Path

import pytest

from firmware.sim import start_simulator
from tests.onboard.ground import Ground, start_agent
from workers.mosquitto import start_broker

from .test_receiver_setup import _switch_args

pytestmark = pytest.mark.e2e

HOME = (40.6303, -8.6575, 12.0)
SCALE = 20.0
DRONE = "SKY_ARMSW1"


@pytest.fixture
def broker(tmp_path: Path):  # type: ignore[no-untyped-def]
    b = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    yield b
    b.stop()


@pytest.mark.parametrize("setup", ["Switch+Throttle", "Yaw Right+Throttle"])
def test_the_agent_arms_and_disarms_the_board_as_it_is_set_up(
    tmp_path: Path, broker, setup: str
) -> None:
    extra = _switch_args() if setup == "Switch+Throttle" else []
    sim = start_simulator(home=HOME, time_scale=SCALE, extra_args=extra)
    process = start_agent(
        tmp_path,
        drone_id=DRONE,
        link=sim.url,
        broker_url=broker.url_for(DRONE),
        arming_line=tmp_path / "unused",
        time_scale=SCALE,
        extra=["--arming", "uavtalk-receiver"],
    )
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"], timeout=15)
        assert ground.command("arm")["result"] == {"armed": True}
        beat = ground.wait_for("heartbeats", lambda m: m["armed"])
        assert not beat["fc"].get("setup")
        assert ground.command("disarm")["result"] == {"armed": False}
        ground.wait_for("heartbeats", lambda m: not m["armed"])
        assert ground.command("arm")["result"] == {"armed": True}  # and again
    finally:
        ground.close()
        process.stop()
        sim.stop()

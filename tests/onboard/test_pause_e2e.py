"""Mission pause and resume end to end: the real agent process flying the simulator, real
Mosquitto, the ground a plain MQTT client."""

from __future__ import annotations

import time
from collections import Counter

import pytest

from onboard import protocol

from .test_failsafe_e2e import _north, _on_the_ground_disarmed, broker, fly  # noqa: F401

pytestmark = pytest.mark.e2e

STEPS = [
    {"index": 0, "command": "arm"},
    {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
    {"index": 2, "command": "wait_for_flight"},
    {"index": 3, "command": "changeN", "params": {"value": 400}},
    {"index": 4, "command": "wait_for_flight"},
    {"index": 5, "command": "land"},
    {"index": 6, "command": "wait_for_flight"},
]


def _reply(ground, request: protocol.MissionPause) -> dict:
    ground.send("mission", request.to_dict())
    return ground.wait_for("mission", lambda m: m.get("request_id") == request.request_id, 10)


def _beat_after(ground, since: float) -> dict:
    return ground.wait_for("heartbeats", lambda m: m["ts"] > since and m["position"], 10)


@pytest.mark.parametrize("fc", ["uavtalk", "mavlink"])
def test_hold_and_resume_mid_mission_completes_every_step_once(fly, fc: str) -> None:  # noqa: F811
    """Rule: a paused mission holds the drone where it is; resumed, it carries on from the
    step it was on and reports every step exactly once."""
    ground = fly(fc)
    start = protocol.mission_start("patrol", "a-patrol", STEPS)
    ground.send("mission", start.to_dict())
    ground.wait_for("heartbeats", lambda m: 20 < _north(m) < 300, 60)

    assert _reply(ground, protocol.mission_pause("patrol", "pause"))["status"] == "paused"
    time.sleep(1.0)  # let the drone brake
    first = _north(_beat_after(ground, time.time()))
    time.sleep(1.5)  # 30 flight seconds at the test's time scale
    held = _north(_beat_after(ground, time.time()))
    assert held == pytest.approx(first, abs=1.5) and held < 350
    assert ground.on("mission")[-1]["status"] == "paused"  # no step ended while paused

    assert _reply(ground, protocol.mission_pause("patrol", "resume"))["status"] == "resumed"
    end = ground.wait_for(
        "mission", lambda m: m.get("type") == "mission" and m["status"] == "completed", 60
    )
    assert end["mission_id"] == "patrol"
    reports = Counter(
        (m["index"], m["status"]) for m in ground.on("mission") if m.get("type") == "step"
    )
    assert reports == {(i, s): 1 for i in range(len(STEPS)) for s in ("started", "completed")}
    assert _north(_beat_after(ground, time.time())) == pytest.approx(400, abs=2.5)


def test_operator_hold_pauses_the_mission_and_return_brings_the_drone_home(fly) -> None:  # noqa: F811
    """Rule: the operator's hold pauses a running mission where the drone is; return flies
    it home at its altitude, lands and disarms; on the ground both are refused."""
    ground = fly("uavtalk")
    refused = ground.command("hold")
    assert refused["ok"] is False and "on the ground" in refused["error"]
    ground.send("mission", protocol.mission_start("patrol", "a-patrol", STEPS).to_dict())
    ground.wait_for("heartbeats", lambda m: 20 < _north(m) < 300, 60)

    held = ground.command("hold")
    assert held["ok"] is True and held["result"] == {"mode": "hold", "mission_paused": "patrol"}
    ground.wait_for("mission", lambda m: m.get("status") == "paused", 10)
    time.sleep(1.0)
    first = _north(_beat_after(ground, time.time()))
    time.sleep(1.0)
    assert _north(_beat_after(ground, time.time())) == pytest.approx(first, abs=1.5)

    returning = ground.command("return")
    assert returning["ok"] is True and returning["result"] == {"mode": "return"}
    stopped = ground.wait_for("mission", lambda m: m.get("status") == "stopped", 10)
    assert stopped["mission_id"] == "patrol"
    home = _on_the_ground_disarmed(ground, time.time(), 60)
    assert _north(home) == pytest.approx(0, abs=2.5)

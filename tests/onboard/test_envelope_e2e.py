"""The drone's own flight envelope, end to end: the real agent, the simulator, Mosquitto.

Commands and mission steps are published straight to the drone's topics, as a bridge, a
stale broker queue or a ground bug could, so only the agent stands between them and the
flight controller.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from onboard import envelope as env
from onboard import protocol
from runtime.processes import wait_for

from .ground import Ground
from .test_e2e import DRONE, HOME, _pos, agent_for, broker, sim  # noqa: F401 (fixtures)

pytestmark = pytest.mark.e2e

METRES_PER_DEGREE = 111_320


def envelope_message(max_height: float, exclusion_east: float) -> dict:
    center = env.ned_to_latlon(0.0, exclusion_east, HOME)
    envelope = {
        "max_height": max_height,
        "max_distance": 150,
        "geoFence": {
            "version": 2,
            "polygons": [],
            "circles": [
                {
                    "inclusion": False,
                    "circle": {"center": list(center), "radius": 20},
                    "version": 1,
                }
            ],
        },
    }
    return protocol.EnvelopeUpdate(envelope).to_dict()


def refused(ground: Ground, command: str, words: str, **params: float) -> None:
    reply = ground.command(command, **params)
    assert reply["ok"] is False, reply
    assert "flight envelope" in reply["error"] and words in reply["error"], reply["error"]


def test_the_agent_refuses_moves_outside_its_envelope_and_keeps_it(
    broker,  # noqa: F811
    agent_for,  # noqa: F811
    tmp_path: Path,
) -> None:
    stored = tmp_path / "state" / "envelope.json"
    agent_for(broker.url_for(DRONE), "--envelope-file", str(stored))
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=15)
        ground.send("envelope", {"type": "envelope", "envelope": {"max_height": "x"}, "ts": 1})
        ground.send("envelope", envelope_message(30, exclusion_east=60))
        assert ground.command("arm")["ok"]
        assert ground.command("takeoff", altitude=10)["ok"]
        ground.wait_for("heartbeats", lambda m: _pos(m, "alt") > 9.5)
        refused(ground, "altitude", "maximum height of 30 m", value=25)
        refused(ground, "changeN", "maximum distance of 150 m", value=200)
        refused(ground, "changeE", "exclusion circle 0", value=60)
        assert json.loads(stored.read_text())["max_height"] == 30  # the malformed one was dropped

        start = protocol.mission_start(
            "m1", "a1", [{"index": 0, "command": "changeN", "params": {"value": 500}}]
        )
        ground.send("mission", start.to_dict())
        failed = ground.wait_for("mission", lambda m: m.get("status") == "failed")
        assert "maximum distance" in failed["error"]
        ground.wait_for("mission", lambda m: m.get("status") == "stopped")
        assert ground.command("changeN", value=40)["ok"]
    finally:
        ground.close()


def test_a_drone_found_outside_stops_raises_an_alarm_and_returns(
    broker,  # noqa: F811
    agent_for,  # noqa: F811
) -> None:
    agent_for(broker.url_for(DRONE))
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=15)
        assert ground.command("arm")["ok"]
        assert ground.command("takeoff", altitude=30)["ok"]
        assert ground.command("changeN", value=50)["ok"]
        ground.wait_for("heartbeats", lambda m: _pos(m, "alt") > 29 and _pos(m, "lat") > HOME[0])
        time.sleep(0.5)
        # The limit drops under the drone: it is now outside, as wind could have put it.
        ground.send("envelope", envelope_message(20, exclusion_east=500))
        alarm = ground.wait_for("alarms", lambda m: "envelope" in m["message"])
        assert alarm["level"] == "CRITICAL" and "maximum height of 20 m" in alarm["message"]
        seen = len(ground.on("heartbeats"))

        def back_inside() -> list[dict]:
            return [
                m
                for m in ground.on("heartbeats")[seen:]
                if 15 < _pos(m, "alt") < 20.5 and abs(_pos(m, "lat") - HOME[0]) < 2e-5
            ]

        assert wait_for(back_inside, timeout=60), ground.on("heartbeats")[-1]
        assert ground.command("altitude", value=5)["ok"] is False  # 25 m is above 20 m
    finally:
        ground.close()

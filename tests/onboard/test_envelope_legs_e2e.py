"""The drone's own check of the legs it flies, end to end: the real agent, the simulator,
Mosquitto. Commands and mission steps are published straight to the drone's topics, so
only the agent stands between them and the flight controller."""

from __future__ import annotations

import pytest

from onboard import protocol

from .test_e2e import HOME, _pos
from .test_envelope_e2e import envelope_message
from .test_failsafe_e2e import broker, fly  # noqa: F401 (fixtures)

pytestmark = pytest.mark.e2e


@pytest.mark.parametrize("fc", ["uavtalk", "mavlink"])
def test_the_agent_refuses_a_leg_across_an_exclusion_zone_and_flies_one_beside_it(
    fly,  # noqa: F811
    fc: str,
) -> None:
    ground = fly(fc)
    # An exclusion circle of 20 m, 60 m east of home.
    ground.send("envelope", envelope_message(100, exclusion_east=60))
    assert ground.command("arm")["ok"]
    assert ground.command("takeoff", altitude=10)["ok"]
    ground.wait_for("heartbeats", lambda m: _pos(m, "alt") > 9.5)
    # 120 m east ends outside the zone, but the straight leg goes through it.
    reply = ground.command("changeE", value=120)
    assert reply["ok"] is False, reply
    assert "flight envelope" in reply["error"] and "exclusion circle 0" in reply["error"]

    start = protocol.mission_start(
        "m1", "a1", [{"index": 0, "command": "changeE", "params": {"value": 120}}]
    )
    ground.send("mission", start.to_dict())
    failed = ground.wait_for("mission", lambda m: m.get("status") == "failed")
    assert "exclusion circle 0" in failed["error"]
    # The stopped mission's hold is in place before its end is reported; a command sent
    # after that starts from the hold.
    ground.wait_for("mission", lambda m: m.get("status") == "stopped")

    # 30 m north first, then east: the leg passes 30 m from the zone's centre. Sent
    # before the drone is there it would turn east from where it is, across the zone (the
    # agent refuses that: test_envelope_shortcuts.py), so it is sent once it has arrived.
    assert ground.command("changeN", value=30)["ok"]
    ground.wait_for("heartbeats", lambda m: _pos(m, "lat") > HOME[0] + 28.5 / 111_320)
    beside = ground.command("changeE", value=120)
    assert beside["ok"] is True, beside
    assert beside["result"]["target"]["east"] == pytest.approx(120.0)

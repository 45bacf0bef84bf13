"""The real agent and the MAVLink simulator's Remote ID module: the identity the ground
sends with the envelope reaches the module as Open Drone ID messages (the simulator logs
what it received), and the module's arm status comes back in the heartbeat."""

from __future__ import annotations

import ast
import re
import time
from pathlib import Path

import pytest

from onboard import protocol
from tests.onboard.ground import Ground
from tests.onboard.mavlink.conftest import autopilot  # noqa: F401 (fixture)
from tests.onboard.mavlink.test_agent import broker, fly  # noqa: F401 (fixtures)

pytestmark = pytest.mark.e2e

SERIAL = "MFR1C123456789ABC"
OPERATOR = "FIN87astrdge12k8"
STATION = (40.6301, -8.6579)


def send_identity(ground: Ground) -> None:
    identity = protocol.RemoteIdentity(
        serial_number=SERIAL,
        operator_id=OPERATOR,
        description="Survey north field",
        operator_location=STATION,
        eu_category=1,  # open
        eu_class=3,  # C2
    )
    ground.send("envelope", protocol.EnvelopeUpdate({}, remote_id=identity).to_dict())


# The agent sends the four messages one after another once a second (onboard/remote_id.py).
# The module is good to arm on the first two, so the heartbeat saying so can come before
# the simulator has logged the other two: up to ten rounds of sends are waited for.
# Measured: all four already logged when the heartbeat said good, three times quiet and
# three times beside four busy processes; once, beside the suite's parallel tests, the
# third was not yet logged.
LOGGED_WITHIN_S = 10.0
# Three of the module's beats, one a second.
MODULE_BEATS_S = 3.5


def _logged(tmp_path: Path, kind: str) -> list[str]:
    return re.findall(rf"Remote ID {kind}: (\{{.*\}})", (tmp_path / "sim.log").read_text())


def received(tmp_path: Path, kind: str) -> dict:
    """The last fields of `kind` the simulator's Remote ID module logged, once it has."""
    deadline = time.monotonic() + LOGGED_WITHIN_S
    while not (found := _logged(tmp_path, kind)):
        assert time.monotonic() < deadline, f"the module logged no {kind}"
        time.sleep(0.05)
    return ast.literal_eval(found[-1])


def test_the_module_gets_the_identity_and_reports_good_to_arm(fly, tmp_path):  # noqa: F811
    ground = fly(sim_args=("--remote-id",))
    # Before any identity the module refuses: it has nothing to broadcast.
    waiting = ground.wait_for("heartbeats", lambda m: "remote_id" in m, 20)
    assert waiting["remote_id"]["ok"] is False
    send_identity(ground)
    since = time.time()
    good = ground.wait_for(
        "heartbeats", lambda m: m["ts"] > since and m.get("remote_id", {}).get("ok"), 20
    )
    assert good["remote_id"] == {"ok": True, "error": "", "source": "odid"}
    basic = received(tmp_path, "OPEN_DRONE_ID_BASIC_ID")
    assert basic["uas_id"] == SERIAL
    assert basic["id_type"] == 1  # MAV_ODID_ID_TYPE_SERIAL_NUMBER
    assert basic["ua_type"] == 2  # helicopter or multirotor
    assert received(tmp_path, "OPEN_DRONE_ID_OPERATOR_ID")["operator_id"] == OPERATOR
    assert received(tmp_path, "OPEN_DRONE_ID_SELF_ID")["description"] == "Survey north field"
    system = received(tmp_path, "OPEN_DRONE_ID_SYSTEM")
    assert system["operator_location_type"] == 2  # fixed: the position the ground gave
    assert (system["operator_latitude"], system["operator_longitude"]) == (
        round(STATION[0] * 1e7),
        round(STATION[1] * 1e7),
    )
    assert system["classification_type"] == 1  # EU: an EN 4709-002 operator number
    assert (system["category_eu"], system["class_eu"]) == (1, 3)
    assert ground.command("arm")["ok"]
    # The module beats as well, as ArduRemoteID does (type ODID, autopilot ArduPilot,
    # nothing armed): the agent keeps to the flight controller's own heartbeat.
    armed_at = time.time()
    time.sleep(MODULE_BEATS_S)
    beats = [m for m in ground.on("heartbeats") if m["ts"] > armed_at]
    assert beats and all(m["armed"] for m in beats), beats


def test_a_failing_module_is_reported_and_refuses_arming(fly):  # noqa: F811
    ground = fly(sim_args=("--remote-id-fail", "transmitter fault"))
    send_identity(ground)
    beat = ground.wait_for("heartbeats", lambda m: "remote_id" in m, 20)
    assert beat["remote_id"] == {"ok": False, "error": "transmitter fault", "source": "odid"}
    reply = ground.command("arm")
    assert not reply["ok"]
    assert "OpenDroneID: transmitter fault" in reply["error"]


def test_without_a_module_an_identity_is_reported_unanswered(fly):  # noqa: F811
    ground = fly()
    assert all("remote_id" not in m for m in ground.on("heartbeats"))
    send_identity(ground)
    beat = ground.wait_for("heartbeats", lambda m: "remote_id" in m, 20)
    assert beat["remote_id"]["ok"] is False
    assert "no OPEN_DRONE_ID_ARM_STATUS" in beat["remote_id"]["error"]

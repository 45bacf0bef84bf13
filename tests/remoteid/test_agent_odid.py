"""The real agent and the MAVLink simulator's Remote ID module: the identity the ground
sends with the envelope reaches the module as Open Drone ID messages (the simulator logs
what it received), and the module's arm status comes back in the heartbeat."""

from __future__ import annotations

import ast
import re
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from firmware.sim.fleet import agent_process, copy_gear
from onboard import protocol
from runtime.processes import Supervised
from tests.onboard.ground import Ground
from tests.onboard.mavlink.conftest import HOME, TIME_SCALE
from workers.mosquitto import start_broker

pytestmark = pytest.mark.e2e

DRONE = "MAV_RID01"
SERIAL = "MFR1C123456789ABC"
OPERATOR = "FIN87astrdge12k8"
STATION = (40.6301, -8.6579)


@pytest.fixture
def broker(tmp_path: Path):  # type: ignore[no-untyped-def]
    b = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    yield b
    b.stop()


@pytest.fixture
def fly(tmp_path: Path, broker):  # type: ignore[no-untyped-def]
    """fly(*sim_args) → a Ground talking to the agent of a MAVLink sim started with them."""
    started: list = []

    def start(*sim_args: str) -> Ground:
        sim = start_simulator(
            home=HOME,
            time_scale=TIME_SCALE,
            fc="mavlink",
            extra_args=list(sim_args),
            log_file=tmp_path / "sim.log",
        )
        started.append(sim)
        copy_gear(tmp_path)
        agent = agent_process(
            DRONE,
            tmp_path,
            sim.link_url,
            broker.url_for(DRONE),
            fc="mavlink",
            time_scale=TIME_SCALE,
            extra=["--heartbeat-interval", "0.5", "--arm-timeout", "6"],
        ).start()
        started.append(agent)
        ground = Ground(broker.port, DRONE)
        started.append(ground)
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"], 20)
        return ground

    yield start
    for thing in reversed(started):
        if isinstance(thing, Supervised):
            assert thing.stop() == 0, "the agent did not stop cleanly"
        elif isinstance(thing, Ground):
            thing.close()
        else:
            thing.stop()


def send_identity(ground: Ground) -> None:
    identity = protocol.RemoteIdentity(
        serial_number=SERIAL,
        operator_id=OPERATOR,
        description="Survey north field",
        operator_location=STATION,
    )
    ground.send("envelope", protocol.EnvelopeUpdate({}, remote_id=identity).to_dict())


def received(tmp_path: Path, kind: str) -> dict | None:
    """The last fields of `kind` the simulator's Remote ID module logged."""
    found = re.findall(rf"Remote ID {kind}: (\{{.*\}})", (tmp_path / "sim.log").read_text())
    return ast.literal_eval(found[-1]) if found else None


def test_the_module_gets_the_identity_and_reports_good_to_arm(fly, tmp_path):
    ground = fly("--remote-id")
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
    assert ground.command("arm")["ok"]


def test_a_failing_module_is_reported_and_refuses_arming(fly):
    ground = fly("--remote-id-fail", "transmitter fault")
    send_identity(ground)
    beat = ground.wait_for("heartbeats", lambda m: "remote_id" in m, 20)
    assert beat["remote_id"] == {"ok": False, "error": "transmitter fault", "source": "odid"}
    reply = ground.command("arm")
    assert not reply["ok"]
    assert "OpenDroneID: transmitter fault" in reply["error"]


def test_without_a_module_an_identity_is_reported_unanswered(fly):
    ground = fly()
    assert all("remote_id" not in m for m in ground.on("heartbeats"))
    send_identity(ground)
    beat = ground.wait_for("heartbeats", lambda m: "remote_id" in m, 20)
    assert beat["remote_id"]["ok"] is False
    assert "no OPEN_DRONE_ID_ARM_STATUS" in beat["remote_id"]["error"]

"""The onboard agent with `--fc mavlink` end to end: real agent process, the simulator's
MAVLink personality over TCP, a private Mosquitto; the ground is a plain MQTT client."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from firmware.sim.fleet import agent_process, copy_gear
from onboard import protocol
from runtime.processes import Supervised
from tests.onboard.ground import Ground
from workers.mosquitto import start_broker

from .conftest import HOME, TIME_SCALE, wait_for

pytestmark = pytest.mark.e2e

DRONE = "MAV_E2E01"


@pytest.fixture
def broker(tmp_path: Path):  # type: ignore[no-untyped-def]
    b = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    yield b
    b.stop()


@pytest.fixture
def fly(tmp_path: Path, broker, autopilot):  # type: ignore[no-untyped-def]
    """fly(*sim_params, agent_args=(), sim_args=()) → Ground talking to an agent flying a
    MAVLink sim (ArduPilot, or PX4 where the test parametrizes `autopilot`); `sim_args`
    are further simulator options (`--remote-id`)."""
    started: list = []

    def start(  # type: ignore[no-untyped-def]
        *params: str,
        agent_args: tuple[str, ...] = (),
        sim_args: tuple[str, ...] = (),
        **sim_kwargs,
    ) -> Ground:
        extra = [arg for p in params for arg in ("--param", p)] + ["--autopilot", autopilot]
        extra += list(sim_args)
        sim = start_simulator(
            home=HOME,
            time_scale=TIME_SCALE,
            fc="mavlink",
            extra_args=extra,
            log_file=tmp_path / "sim.log",
            **sim_kwargs,
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
            extra=["--heartbeat-interval", "0.5", "--arm-timeout", "6", *agent_args],
        ).start()
        started.append(agent)
        ground = Ground(broker.port, DRONE)
        started.append(ground)
        ground.wait_for(
            "heartbeats", lambda m: m["fc"]["connected"] and m["position"] is not None, 20
        )
        return ground

    yield start
    for thing in reversed(started):
        if isinstance(thing, Supervised):
            assert thing.stop() == 0, "the agent did not stop cleanly"
        elif isinstance(thing, Ground):
            thing.close()
        else:
            thing.stop()


def agent_log(tmp_path: Path) -> str:
    return (tmp_path / "agent.log").read_text(errors="replace")


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_ground_flies_a_mavlink_drone_through_the_agent(fly, tmp_path):
    ground = fly()
    beat = ground.on("heartbeats")[-1]
    assert beat["fc"] == {"protocol": "mavlink", "connected": True}
    assert ground.command("arm")["ok"]
    reply = ground.command("takeoff", altitude=10)
    assert reply["ok"], reply
    ground.wait_for("heartbeats", lambda m: m["airborne"] and m["position"]["alt"] > 9.5, 10)
    lat, lon = HOME[0] + 0.0003, HOME[1] + 0.0002
    assert ground.command("navigate", lat=lat, lon=lon)["ok"]
    ground.wait_for(
        "heartbeats",
        lambda m: (
            m["position"] is not None
            and abs(m["position"]["lat"] - lat) < 2e-6
            and abs(m["position"]["lon"] - lon) < 2e-6
        ),
        10,
    )
    landing = time.time()
    assert ground.command("land")["ok"]
    ground.wait_for(
        "heartbeats",
        lambda m: m["ts"] > landing and not m["armed"] and m["position"]["alt"] < 0.1,
        15,
    )
    # The flight controller's own words reach the agent's log.
    assert "flight controller says: Arming motors" in agent_log(tmp_path)


def test_telemetry_carries_mavlink_messages_and_platform_objects(fly):
    ground = fly()

    def names() -> set[str]:
        return {o["name"] for m in ground.on("telemetry") for o in m["objects"]}

    assert wait_for(
        lambda: (
            {"ATTITUDE", "AttitudeActual", "GLOBAL_POSITION_INT", "FlightBatteryState"} <= names()
        ),
        5,
    ), names()
    objrequest = ground.command("objrequest", value="ATTITUDE")
    assert objrequest["ok"] and {"roll", "pitch", "yaw"} <= set(objrequest["result"])


def test_a_refused_arm_is_answered_with_the_mavlink_result_named(fly):
    ground = fly("BATT_CRT_PCT=100")
    reply = ground.command("arm")
    assert not reply["ok"]
    assert "MAV_RESULT_DENIED" in reply["error"] and "Battery critical" in reply["error"]


def test_a_command_the_vehicle_never_answers_gets_a_timeout_reply_and_the_agent_goes_on(fly):
    ground = fly("SIM_CMD_MUTE=400")
    reply = ground.command("arm", timeout=15)
    assert not reply["ok"]
    assert "No COMMAND_ACK for MAV_CMD_COMPONENT_ARM_DISARM" in reply["error"]
    assert ground.command("objrequest", value="HEARTBEAT")["ok"]


def test_junk_frames_from_the_vehicle_are_counted_and_the_agent_keeps_flying(fly):
    ground = fly("SIM_JUNK_RATE=40")

    def link_stats() -> dict:
        for message in reversed(ground.on("telemetry")):
            for obj in message["objects"]:
                if obj["name"] == "FlightTelemetryStats":
                    return obj["fields"]
        return {}

    assert wait_for(
        lambda: link_stats().get("RxFailures", 0) > 5 and link_stats().get("RxUnknown", 0) > 5, 5
    ), link_stats()
    assert ground.command("arm")["ok"]
    assert ground.command("takeoff", altitude=5)["ok"]
    ground.wait_for("heartbeats", lambda m: m["airborne"] and m["position"]["alt"] > 4.5, 10)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_agent_flies_a_mission_natively_when_asked(fly):
    ground = fly(agent_args=("--native-missions",))
    steps = [
        {"index": 0, "command": "arm", "params": {}},
        {"index": 1, "command": "takeoff", "params": {"altitude": 8}},
        {"index": 2, "command": "changeN", "params": {"value": 25}},
        {"index": 3, "command": "wait_for_flight", "params": {}},
        {"index": 4, "command": "changeE", "params": {"value": 15}},
        {"index": 5, "command": "wait_for_flight", "params": {}},
        {"index": 6, "command": "land", "params": {}},
        {"index": 7, "command": "disarm", "params": {}},
    ]
    start = protocol.mission_start("NM1", "NA1", steps)
    ground.send("mission", start.to_dict())
    done = ground.wait_for(
        "mission", lambda m: m["type"] == "mission" and m["status"] in ("completed", "stopped"), 40
    )
    assert done["status"] == "completed", ground.on("mission")[-4:]
    completed = [
        m["index"]
        for m in ground.on("mission")
        if m.get("type") == "step" and m["status"] == "completed"
    ]
    assert completed == list(range(8))
    landed = [m for m in ground.on("mission") if m.get("index") == 6 and m["status"] == "completed"]
    position = landed[0]["position"]
    north_m = (position["lat"] - HOME[0]) * 111_000
    # Touched down (the step reports the last position sample, one stream period late).
    assert 20 < north_m < 30 and position["alt"] < 0.5


def latest_yaw(ground: Ground) -> float | None:
    for message in reversed(ground.on("telemetry")):
        for obj in message["objects"]:
            if obj["name"] == "AttitudeActual":
                return obj["fields"]["Yaw"] % 360.0
    return None


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_mission_leg_facing_a_region_of_interest_flies_through_the_agent(fly):
    """A `roi` leg is accepted on MAVLink: the agent points the nose step by step (also with
    native missions, which fly the landing), and the drone ends facing the point."""
    ground = fly(agent_args=("--native-missions",))
    north_per_deg = 111_195.0
    target = (HOME[0] + 40 / north_per_deg, HOME[1])
    roi = (HOME[0], HOME[1] + 40 / (north_per_deg * math.cos(math.radians(HOME[0]))))
    steps = [
        {"index": 0, "command": "arm", "params": {}},
        {"index": 1, "command": "takeoff", "params": {"altitude": 8}},
        {"index": 2, "command": "wait_for_flight", "params": {}},
        {
            "index": 3,
            "command": "navigate",
            "params": {"lat": target[0], "lon": target[1], "roi": list(roi)},
        },
        {"index": 4, "command": "wait_for_flight", "params": {}},
        {"index": 5, "command": "land", "params": {}},
        {"index": 6, "command": "disarm", "params": {}},
    ]
    ground.send("mission", protocol.mission_start("RM1", "RA1", steps).to_dict())
    done = ground.wait_for(
        "mission",
        lambda m: m["type"] == "mission" and m["status"] in ("completed", "stopped", "rejected"),
        40,
    )
    assert done["status"] == "completed", ground.on("mission")[-4:]
    # From 40 m north of home the ROI, 40 m east of home, lies to the south-east (135°);
    # the flight itself went north (0°). The landing kept the heading.
    assert wait_for(lambda: abs(((latest_yaw(ground) or 0.0) - 135.0 + 180) % 360 - 180) < 5, 5), (
        latest_yaw(ground)
    )

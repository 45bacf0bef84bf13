"""End to end: the real agent process, the simulator over a real pty, real Mosquitto."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from onboard import protocol
from onboard.bridge import bridge_config
from runtime.processes import stop_process
from workers.mosquitto import start_broker

from .dfi_rules import check_dfi, labels
from .ground import Ground, start_agent

pytestmark = pytest.mark.e2e

HOME = (40.6303, -8.6575, 12.0)
SCALE = 20.0
DRONE = "SKY_E2E01"


@pytest.fixture
def broker(tmp_path: Path):
    # Persistence on, as a production broker has it: a restart keeps the ground's session.
    store = tmp_path / "store"
    store.mkdir()
    b = start_broker(
        tmp_path / "broker",
        {"ground": "pw", DRONE: "dpw"},
        extra_config=f"persistence true\npersistence_location {store}/\n",
    )
    yield b
    b.stop()


@pytest.fixture
def sim(tmp_path: Path):
    s = start_simulator(
        home=HOME,
        time_scale=SCALE,
        arming_line=tmp_path / "arming_line",
        log_file=tmp_path / "sim.log",
    )
    yield s
    s.stop()


@pytest.fixture
def agent_for(tmp_path: Path, sim):
    started = []

    def start(broker_url: str, *extra: str):
        process = start_agent(
            tmp_path,
            drone_id=DRONE,
            link=sim.url,
            broker_url=broker_url,
            arming_line=tmp_path / "arming_line",
            time_scale=SCALE,
            extra=list(extra),
        )
        started.append(process)
        return process

    yield start
    for process in started:
        process.stop()


def _pos(heartbeat: dict, key: str, default: float = 0.0) -> float:
    """A heartbeat's position field; early heartbeats have no position yet."""
    return (heartbeat["position"] or {}).get(key, default)


def test_the_drone_arms_takes_off_flies_north_and_lands_on_command(
    broker, agent_for, tmp_path: Path
) -> None:
    agent_for(broker.url_for(DRONE))
    ground = Ground(broker.port, DRONE)
    try:
        beat = ground.wait_for(
            "heartbeats", lambda m: m["fc"]["connected"] and m["position"] is not None, timeout=15
        )
        assert protocol.parse_heartbeat(beat).armed is False
        announcement = ground.wait_for("gear", lambda m: m.get("type") == "gear")
        assert announcement["specs"]["TYPE"] == "HEXACOPTER"

        refused = ground.command("takeoff", altitude=10)
        assert refused["ok"] is False and "not armed" in refused["error"]
        assert ground.command("arm")["result"] == {"armed": True}
        assert ground.command("takeoff", altitude=10)["ok"]
        up = ground.wait_for("heartbeats", lambda m: _pos(m, "alt") > 9.5)
        assert up["airborne"] is True
        airborne_disarm = ground.command("disarm")
        assert airborne_disarm["ok"] is False and "airborne" in airborne_disarm["error"]

        assert ground.command("changeN", value=100)["ok"]
        north = ground.wait_for("heartbeats", lambda m: _pos(m, "lat") > HOME[0] + 0.00088)
        assert north["position"]["lat"] == pytest.approx(HOME[0] + 100 / 111_320, abs=2e-5)
        landing = time.time()
        assert ground.command("land")["ok"]
        # A landed drone disarms itself after the auto-disarm delay; disarm is then a no-op.
        ground.wait_for(
            "heartbeats",
            lambda m: m["ts"] > landing and _pos(m, "alt", 99) < 0.2 and not m["armed"],
        )
        assert ground.command("disarm")["result"] == {"armed": False}
        status = ground.command("objrequest", value="FlightStatus")
        assert status["result"]["Armed"] == "Disarmed"
        bad = ground.command("objrequest", value="NoSuchObject")
        assert bad["ok"] is False and bad["error"]

        telemetry = ground.on("telemetry")
        names = {o["name"] for m in telemetry for o in m["objects"]}
        assert {"AttitudeActual", "FlightStatus", "GPSPosition"} <= names
    finally:
        ground.close()


def test_malformed_input_is_answered_or_dropped_and_the_agent_lives(broker, agent_for) -> None:
    process = agent_for(broker.url_for(DRONE))
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"], timeout=15)
        ground.client.publish(f"{DRONE}/control/in", b"\xff\xfe not json", qos=1)
        ground.client.publish(f"{DRONE}/mission/in", b"[1, 2]", qos=1)
        rid = protocol.new_request_id()
        ground.send(
            "control", {"request_id": rid, "command": "navigate", "params": {"lat": 91, "lon": 0}}
        )
        reply = ground.wait_for("control", lambda m: m["request_id"] == rid)
        assert reply["ok"] is False and "params.lat" in reply["error"]
        rid = protocol.new_request_id()
        ground.send(
            "mission",
            {
                "request_id": rid,
                "action": "start",
                "mission_id": "m9",
                "assignment_id": "a9",
                "payload": "%%%",
            },
        )
        rejected = ground.wait_for("mission", lambda m: m.get("mission_id") == "m9")
        assert rejected["status"] == "rejected" and "base64" in rejected["error"]
        rid = protocol.new_request_id()
        ground.send("gear", {"request_id": rid, "query": "reading", "sensor": "CO2"})
        reading = ground.wait_for("gear", lambda m: m.get("request_id") == rid)
        assert reading["ok"] and reading["reading"]["unit"] == "ppm"
        assert process.alive
        assert ground.command("objrequest", value="FlightStatus")["ok"]
    finally:
        ground.close()


def test_a_request_delivered_twice_is_acted_on_once(broker, agent_for) -> None:
    """QoS 1 and the ground's outbox deliver at least once: a repeated request id (the
    same mission start, the same command) is done once, answered once."""
    process = agent_for(broker.url_for(DRONE))
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"], timeout=15)
        start = protocol.mission_start(
            "m7", "a7", [{"index": 0, "command": "sleep", "params": {"value": 20}}]
        )
        ground.send("mission", start.to_dict())
        ground.send("mission", start.to_dict())
        command = {"request_id": protocol.new_request_id(), "command": "objrequest",
                   "params": {"value": "FlightStatus"}, "ts": time.time()}  # fmt: skip
        ground.send("control", command)
        ground.send("control", command)
        ground.wait_for("control", lambda m: m["request_id"] == command["request_id"])
        ground.wait_for("mission", lambda m: m.get("type") == "mission")
        # Any second answer would be on its way by the time a fresh command is answered.
        assert ground.command("objrequest", value="FlightStatus")["ok"]
        replies = [m for m in ground.on("control") if m["request_id"] == command["request_id"]]
        assert len(replies) == 1 and replies[0]["ok"], replies
        statuses = [m["status"] for m in ground.on("mission") if m.get("type") == "mission"]
        assert statuses == ["accepted"], ground.on("mission")
        assert process.alive
    finally:
        ground.close()


MISSION = [
    {"index": 0, "command": "arm"},
    {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
    {"index": 2, "command": "wait_for_flight"},
    {"index": 3, "command": "changeN", "params": {"value": 100}},
    {"index": 4, "command": "wait_for_flight", "params": {"horizontal_tolerance": 1.5}},
    {"index": 5, "command": "takepic"},
    {"index": 6, "command": "sense", "params": {"sensor": "CO2"}},
    {"index": 7, "command": "sleep", "params": {"value": 4}},
    {"index": 8, "command": "changeE", "params": {"value": 50}},
    {"index": 9, "command": "wait_for_flight"},
    {"index": 10, "command": "land"},
    {"index": 11, "command": "wait_for_flight", "params": {"vertical_tolerance": 0.5}},
    {"index": 12, "command": "disarm"},
]


def test_a_mission_survives_a_broker_restart_and_its_log_holds_every_step(
    broker, agent_for, tmp_path: Path
) -> None:
    process = agent_for(broker.url_for(DRONE))
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=15)
        start = protocol.mission_start("m1", "a1", MISSION)
        ground.send("mission", start.to_dict())
        accepted = ground.wait_for("mission", lambda m: m.get("type") == "mission")
        assert accepted["status"] == "accepted" and accepted["decode_ms"] > 0
        ground.wait_for("mission", lambda m: m.get("index") == 3 and m["status"] == "started")
        broker.restart(down_for=1.0)  # the mission goes on while the broker is away
        done = ground.wait_for(
            "mission",
            lambda m: m.get("type") == "mission" and m["status"] != "accepted",
            timeout=60,
        )
        assert done["status"] == "completed", done
        steps = [m for m in ground.on("mission") if m.get("type") == "step"]
        seen = {(m["index"], m["status"]) for m in steps}
        expected = {(s["index"], status) for s in MISSION for status in ("started", "completed")}
        assert seen == expected
        completed = {m["index"]: m for m in steps if m["status"] == "completed"}
        assert completed[4]["position"]["lat"] == pytest.approx(HOME[0] + 100 / 111_320, abs=2e-5)
        assert completed[6]["result"]["reading"]["unit"] == "ppm"
        # Flight seconds (wall x time scale): 4 s of sleep, plus scheduling on a busy host.
        # Measured 4.02-4.06 s quiet and 4.04-4.30 s with four busy processes on two cores;
        # 15 leaves 0.5 s of wall time for scheduling at SCALE.
        assert 3.9 <= completed[7]["duration_s"] < 15
        picture = ground.wait_for("pictures", lambda m: True)
        assert picture["name"] == completed[5]["result"]["name"] and picture["index"] == 5
    finally:
        ground.close()
    assert process.stop() == 0
    archives = sorted((tmp_path / "logs").glob("*.dfi"))
    assert archives, list((tmp_path / "logs").iterdir())
    rows = {}
    for archive in archives:
        tables = check_dfi(archive)
        if "steps" in tables:
            status = labels(archive, "steps", "status")
            rows.update({(int(r[2]), status[int(r[4])]): r for r in tables["steps"]})
            assert "AttitudeActual" in tables and "mission" in tables
    assert {index for index, status in rows if status == "completed"} == set(range(13))


def test_a_drone_behind_its_own_broker_is_commanded_through_the_ground_broker(
    broker, agent_for, tmp_path: Path
) -> None:
    internal = start_broker(
        tmp_path / "internal",
        {DRONE: "local"},
        extra_config="\n" + bridge_config(DRONE, broker.url_for(DRONE)),
    )
    try:
        agent_for(internal.url_for(DRONE))
        ground = Ground(broker.port, DRONE)
        try:
            beat = ground.wait_for("heartbeats", lambda m: m["fc"]["connected"], timeout=20)
            assert beat["drone_id"] == DRONE
            deadline = time.monotonic() + 10
            while True:  # the bridge's subscription may lag its first connection a little
                request_id = protocol.new_request_id()
                ground.send(
                    "control",
                    {
                        "request_id": request_id,
                        "command": "objrequest",
                        "params": {"value": "FlightStatus"},
                    },
                )
                try:
                    reply = ground.wait_for(
                        "control", lambda m, rid=request_id: m["request_id"] == rid, timeout=1
                    )
                    break
                except AssertionError:
                    assert time.monotonic() < deadline, "no reply through the bridge"
            assert reply["ok"] and reply["result"]["Armed"] == "Disarmed"
        finally:
            ground.close()
    finally:
        internal.stop()


def test_a_plume_and_a_draining_battery_raise_one_alarm_each(tmp_path: Path) -> None:
    broker = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    sim = start_simulator(
        home=HOME,
        time_scale=SCALE,
        arming_line=tmp_path / "arming_line",
        log_file=tmp_path / "sim.log",
        battery_capacity_mah=200,
    )
    plume = f"{HOME[0] + 100 / 111_320},{HOME[1]},30,2500"
    process = start_agent(
        tmp_path,
        drone_id=DRONE,
        link=sim.url,
        broker_url=broker.url_for(DRONE),
        arming_line=tmp_path / "arming_line",
        time_scale=SCALE,
        extra=[
            "--plume",
            plume,
            "--bounds",
            "CO2::1000",
            "--battery-critical",
            "0.25",
            # What raises the alarms is under test here: no repeat, no fail-safe return.
            "--alarm-repeat",
            "1000",
            "--critical-takeover",
            "1000",
            "--video-rate",
            "5",
            "--pose-rate",
            "20",
        ],
    )
    ground = Ground(broker.port, DRONE)
    try:
        ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=15)
        steps = [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
            {"index": 2, "command": "wait_for_flight"},
            {"index": 3, "command": "changeN", "params": {"value": 100}},
            {"index": 4, "command": "wait_for_flight"},
            {"index": 5, "command": "sense", "params": {"sensor": "CO2"}},
            {"index": 6, "command": "sleep", "params": {"value": 60}},
            {"index": 7, "command": "land"},
            {"index": 8, "command": "wait_for_flight"},
            {"index": 9, "command": "disarm"},
        ]
        ground.send("mission", protocol.mission_start("m2", "a2", steps).to_dict())
        done = ground.wait_for(
            "mission",
            lambda m: m.get("type") == "mission" and m["status"] not in ("accepted",),
            timeout=60,
        )
        assert done["status"] == "completed", done
        alarms = [protocol.parse_alarm(m) for m in ground.on("alarms")]
        assert [a.level for a in alarms] == ["OUT_MEASURE", "CRITICAL"]
        measure, critical = alarms
        assert (measure.sensor, measure.index, measure.mission_id) == ("CO2", 5, "m2")
        assert measure.value > 1000 and measure.position.lat == pytest.approx(
            HOME[0] + 100 / 111_320, abs=3e-5
        )
        assert critical.index == 6 and critical.assignment_id == "a2"
        assert critical.value < 0.25
        frames = [protocol.parse_camera_frame(m) for m in ground.on("camera")]
        assert frames and frames[-1].jpeg.startswith(b"\xff\xd8")
        poses = [o for m in ground.on("telemetry") for o in m["objects"] if o["name"] == "Pose"]
        assert poses and set(poses[-1]["fields"]) >= {"North", "East", "Down", "qw"}
    finally:
        ground.close()
        process.stop()
        sim.stop()
        broker.stop()


def test_the_launcher_starts_a_fleet_with_provisioned_credentials(tmp_path: Path) -> None:
    import json
    import os
    import signal
    import subprocess
    import sys

    users = {"ground": "pw", "SIM_A": "a-secret", "SIM_B": "b:secret@"}
    broker = start_broker(tmp_path / "broker", users)
    creds = [
        {
            "drone_id": d,
            "mqtt": {"host": "127.0.0.1", "port": broker.port, "username": d, "password": users[d]},
        }
        for d in ("SIM_A", "SIM_B")
    ]
    (tmp_path / "creds.json").write_text(json.dumps(creds))
    repo = Path(__file__).resolve().parents[2]
    launcher = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "firmware.sim.fleet",
            "--count",
            "2",
            "--home",
            f"{HOME[0]},{HOME[1]}",
            "--credentials-file",
            str(tmp_path / "creds.json"),
            "--time-scale",
            str(SCALE),
            "--workdir",
            str(tmp_path / "fleet"),
            "--",
            "--heartbeat-interval",
            "0.5",
        ],
        cwd=repo,
        env=dict(os.environ, PYTHONPATH=str(repo)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    grounds = [Ground(broker.port, d, client_id=f"g-{d}") for d in ("SIM_A", "SIM_B")]
    try:
        beats = [
            g.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=30)
            for g in grounds
        ]
        a, b = (protocol.parse_heartbeat(m).position for m in beats)
        assert (a.lat, a.lon) != (b.lat, b.lon)
        assert grounds[1].command("objrequest", value="FlightStatus")["ok"]
        lines = [launcher.stdout.readline().strip() for _ in range(2)]
        agent_pid = int(lines[0].split("agent_pid=")[1].split()[0])
        killed_at = time.time()
        os.kill(agent_pid, signal.SIGKILL)  # the launcher brings the drone back
        grounds[0].wait_for(
            "heartbeats", lambda m: m["ts"] > killed_at + 0.5 and m["fc"]["connected"], timeout=30
        )
    finally:
        for g in grounds:
            g.close()
        assert stop_process(launcher, timeout=20) == 0, launcher.stderr.read()
        broker.stop()
    lines += launcher.stdout.read().splitlines()
    assert [line.split()[1] for line in lines if line.startswith("drone:")] == ["SIM_A", "SIM_B"]
    assert (tmp_path / "fleet" / "SIM_B" / "gear" / "specs.json").exists()


def test_a_bridged_drone_lands_when_the_ground_link_is_lost(
    broker, agent_for, tmp_path: Path
) -> None:
    from onboard.bridge import state_topic
    from workers.mosquitto import GROUND_AND_DRONES_ACL

    acl = f"user {DRONE}\ntopic read $SYS/broker/connection/#\n\n" + GROUND_AND_DRONES_ACL
    internal = start_broker(
        tmp_path / "internal",
        {DRONE: "local", "ground": "pw"},
        acl=acl,
        extra_config="\n" + bridge_config(DRONE, broker.url_for(DRONE)),
    )
    try:
        agent_for(
            internal.url_for(DRONE),
            "--ground-link-topic",
            state_topic(DRONE),
            "--link-loss-timeout",
            "1",
            "--link-loss-action",
            "land",
        )
        ground = Ground(broker.port, DRONE)
        onboard = Ground(internal.port, DRONE, client_id="onboard-watcher")
        try:
            ground.wait_for(
                "heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=20
            )
            assert ground.command("arm")["ok"]
            assert ground.command("takeoff", altitude=10)["ok"]
            ground.wait_for("heartbeats", lambda m: _pos(m, "alt") > 9.5)
            ground.close()
            gone = time.time()
            broker.stop()  # the ground goes away; the drone is on its own
            # Landed, it disarms itself after the auto-disarm delay.
            down = onboard.wait_for(
                "heartbeats",
                lambda m: m["ts"] > gone and not m["armed"] and _pos(m, "alt", 99) < 0.2,
                timeout=20,
            )
            assert down["position"]["lat"] == pytest.approx(HOME[0], abs=1e-5)
            assert "ground link (bridge) down" in (tmp_path / "agent.log").read_text()
        finally:
            onboard.close()
    finally:
        internal.stop()

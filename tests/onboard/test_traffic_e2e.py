"""The agent's traffic check end to end: the real agent process flying the simulator
(UAVTalk over a pty or MAVLink over TCP), real Mosquitto, the ground a plain MQTT client
publishing on `<id>/traffic/in` as the ground's relay does."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from firmware.sim.fleet import agent_process, copy_gear
from onboard import protocol
from onboard.navigation import ned_to_lla
from onboard.traffic import Other, traffic_message
from workers.mosquitto import start_broker

from .ground import Ground

pytestmark = pytest.mark.e2e

HOME = (40.6303, -8.6575, 12.0)
SCALE = 2.0
DRONE = "SKY_TR01"


@pytest.fixture
def drone(tmp_path: Path, request):  # type: ignore[no-untyped-def]
    fc = request.param
    started: list = []
    broker = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: "dpw"})
    started.append(broker)
    line = tmp_path / "arming_line" if fc == "uavtalk" else None
    sim = start_simulator(
        home=HOME, time_scale=SCALE, fc=fc, arming_line=line, log_file=tmp_path / "sim.log"
    )
    started.append(sim)
    copy_gear(tmp_path)
    agent = agent_process(
        DRONE, tmp_path, sim.url, broker.url_for(DRONE), fc=fc, arming_line=line,
        time_scale=SCALE, extra=["--heartbeat-interval", "0.3"],
    ).start()  # fmt: skip
    started.append(agent)
    ground = Ground(broker.port, DRONE)
    started.append(ground)
    ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], 20)
    yield ground, tmp_path / "agent.log"
    for thing in reversed(started):
        if isinstance(thing, Ground):
            thing.close()
        else:
            thing.stop()


def _hovering(ground: Ground, altitude: float = 10.0) -> dict:
    assert ground.command("arm")["ok"]
    assert ground.command("takeoff", altitude=altitude)["ok"]
    return ground.wait_for(
        "heartbeats", lambda m: (m["position"] or {}).get("alt", 0) > altitude - 0.5, 30
    )


def _phantom(north: float, vn: float, alt: float = 10.0) -> Other:
    lat, lon, _ = ned_to_lla(north, 0.0, -alt, HOME)
    return Other("SKY_PH01", lat, lon, alt, 0.0, vn, 0.0, 30.0, 10.0)


def _publish(ground: Ground, payload: bytes) -> None:
    ground.client.publish(f"{DRONE}/traffic/in", payload, qos=0).wait_for_publish(5)


@pytest.mark.parametrize("drone", ["uavtalk", "mavlink"], indirect=True)
def test_malformed_traffic_is_dropped_by_reason_and_a_phantom_head_on_is_held_for(drone):
    ground, agent_log = drone
    before = _hovering(ground)
    good = traffic_message(time.time(), (5.0, 15.0), [_phantom(200, 0)])
    bad = {
        "json": b"{not json",
        "traffic_shape": b"[]",
        "traffic_position": json.dumps({**good, "traffic": [{**good["traffic"][0], "lat": 91}]}),
        "traffic_velocity": json.dumps({**good, "traffic": [{**good["traffic"][0], "vn": "x"}]}),
        "traffic_band": json.dumps({**good, "band": [15, 5]}),
        "traffic_too_many": json.dumps({**good, "traffic": good["traffic"] * 40}),
        "traffic_stale": json.dumps({**good, "ts": time.time() - 60}),
    }
    for payload in bad.values():
        _publish(ground, payload if isinstance(payload, bytes) else payload.encode())
    # Still answering, and nothing moved it: no alarm, the same place.
    assert ground.command("objrequest", value="FlightStatus")["ok"]
    text = agent_log.read_text()
    for reason in bad:
        assert text.count(f"dropped message on {DRONE}/traffic/in ({reason})") == 1, reason
    assert not [a for a in ground.on("alarms") if "Separation" in a["message"]]
    here = ground.on("heartbeats")[-1]["position"]
    assert abs(here["lat"] - before["position"]["lat"]) < 2e-5

    # A drone 55 m north at the same height coming at 10 m/s (ground seconds): within
    # 30 m after 2.5 s, inside the agent's 6 flight-second horizon at twice real time.
    _publish(ground, json.dumps(traffic_message(time.time(), None, [_phantom(55, -10)])).encode())
    alarm = ground.wait_for("alarms", lambda m: "Separation: SKY_PH01" in m["message"], 10)
    assert alarm["level"] == "CRITICAL" and "holding here" in alarm["message"]
    assert "fail-safe hold" in agent_log.read_text()


METRE_LAT = 1 / 111_320


def _north(beat: dict) -> float:
    return ((beat["position"] or {}).get("lat", HOME[0]) - HOME[0]) / METRE_LAT


@pytest.mark.parametrize("drone", ["uavtalk", "mavlink"], indirect=True)
def test_a_drone_flying_a_mission_pauses_it_before_a_drone_ahead(drone):
    """As the operator's Hold: the mission is paused (the operator resumes it), the drone
    hovers short of the minima and the CRITICAL alarm names the other drone."""
    ground, _ = drone
    steps = [
        {"index": 0, "command": "arm"},
        {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
        {"index": 2, "command": "wait_for_flight"},
        {"index": 3, "command": "changeN", "params": {"value": 300}},
        {"index": 4, "command": "wait_for_flight"},
    ]
    ground.send("mission", protocol.mission_start("north", "a-north", steps).to_dict())
    moving = ground.wait_for("heartbeats", lambda m: _north(m) > 10, 40)
    ahead = _north(moving) + 80
    # Standing 80 m ahead, relayed once a second as the ground does.
    for _ in range(3):
        _publish(ground, json.dumps(traffic_message(time.time(), None, [_phantom(ahead, 0)])).encode())  # fmt: skip
        if any("Separation: SKY_PH01" in a["message"] for a in ground.on("alarms")):
            break
        time.sleep(1.0)
    paused = ground.wait_for("mission", lambda m: m.get("status") == "paused", 10)
    assert paused["mission_id"] == "north"
    alarm = ground.wait_for("alarms", lambda m: "Separation: SKY_PH01" in m["message"], 5)
    assert alarm["level"] == "CRITICAL"
    time.sleep(4.0)  # braked and settled
    first = ground.on("heartbeats")[-1]
    time.sleep(1.5)
    last = ground.on("heartbeats")[-1]
    assert ahead - _north(last) >= 30.0, (ahead, _north(last))
    assert abs(_north(last) - _north(first)) < 1.5  # hovering: nothing resumed it

"""Gear, sensors, fail-safe, heartbeats, arming line, bridge config, launcher credentials."""

from __future__ import annotations

import ast
import json
import os
from pathlib import Path

import pytest

from firmware.sim.fleet import broker_url_for, parse_credentials, spread
from onboard import protocol
from onboard.arming import SimulatedLine, UAVTalkReceiverSwitch
from onboard.bridge import bridge_config, internal_broker_config
from onboard.gear import GearError, GearManager
from onboard.heartbeat import build_heartbeat, derive_drone_id
from onboard.navigation import ned_to_lla
from onboard.sensors import SensorField, parse_plume_option
from runtime.processes import wait_for

from .fakes import HOME, FakeFlightController

EXAMPLE = Path(__file__).resolve().parents[2] / "onboard" / "gear_example"


@pytest.fixture
def gear_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "gear"
    folder.mkdir()
    for name in ("specs.json", "sensors.json"):
        (folder / name).write_text((EXAMPLE / name).read_text())
    return folder


def test_gear_files_are_read_and_changes_are_detected(gear_dir: Path) -> None:
    sent = []
    gear = GearManager(gear_dir, lambda channel, m: sent.append((channel, m)))
    assert gear.specs["BATTERY"] == {"CELL_COUNT": 4, "CAPACITY": 5500}
    assert gear.sensors["GAS"] == {"CO2": "Sensirion SCD30"}
    assert gear.reload() is False
    (gear_dir / "specs.json").write_text(json.dumps({"TYPE": "QUADCOPTER"}))
    assert gear.reload() is True
    assert gear.announcement().specs == {"TYPE": "QUADCOPTER"}


def test_a_broken_gear_file_keeps_the_last_good_one(gear_dir: Path) -> None:
    gear = GearManager(gear_dir, lambda *a: None)
    (gear_dir / "sensors.json").write_text("{not json")
    assert gear.reload() is False
    assert gear.sensors["CAMERA"] == "GoPro Hero3"
    assert gear.errors == 1


def test_gear_queries_are_answered(gear_dir: Path) -> None:
    gear = GearManager(gear_dir, lambda *a: None)
    fc = FakeFlightController()
    rid = protocol.new_request_id()
    reply = gear.handle_query(protocol.GearQuery(rid, "specs"), fc.state)
    assert reply.ok and reply.specs["TYPE"] == "HEXACOPTER"
    reply = gear.handle_query(protocol.GearQuery(rid, "reading", "CO2"), fc.state)
    assert reply.ok and reply.reading["value"] == 415.0 and reply.reading["unit"] == "ppm"
    reply = gear.handle_query(protocol.GearQuery(rid, "reading", "O3"), fc.state)
    assert not reply.ok and "no sensor named 'O3'" in reply.error


def test_a_co2_plume_raises_readings_near_its_centre(gear_dir: Path) -> None:
    centre = ned_to_lla(100.0, 0.0, 0.0, HOME)
    field = SensorField(plumes=[parse_plume_option(f"{centre[0]},{centre[1]},30,2000")])
    gear = GearManager(gear_dir, lambda *a: None, sensor_field=field)
    fc = FakeFlightController()
    assert gear.read("CO2", fc.state)["value"] == 415.0
    fc.move_to(100.0, 0.0, -10.0)
    assert gear.read("CO2", fc.state)["value"] == pytest.approx(2000.0, abs=1)
    fc.move_to(115.0, 0.0, -10.0)
    assert gear.read("CO2", fc.state)["value"] == pytest.approx(1207.5, abs=2)


def test_a_sensor_field_file_in_the_gear_folder_is_used(gear_dir: Path) -> None:
    (gear_dir / "sensor_field.json").write_text(
        json.dumps({"baseline": {"CO2": 500}, "plumes": []})
    )
    gear = GearManager(gear_dir, lambda *a: None)
    assert gear.read("CO2", FakeFlightController().state)["value"] == 500.0


def test_pictures_are_stored_and_published(gear_dir: Path, tmp_path: Path) -> None:
    sent = []
    gear = GearManager(gear_dir, lambda c, m: sent.append((c, m)), pictures_dir=tmp_path / "p")
    fc = FakeFlightController()
    fc.move_to(20.0, 5.0, -15.0)
    result = gear.take_picture(fc.state, {"mission_id": "m", "index": 3})
    assert result["name"] == "IMG_0001.JPG"
    assert gear.take_picture(fc.state)["name"] == "IMG_0002.JPG"
    stored = (tmp_path / "p" / "IMG_0001.JPG").read_bytes()
    channel, picture = sent[0]
    assert channel == "pictures" and picture.jpeg == stored and stored[:2] == b"\xff\xd8"
    assert picture.mission_id == "m" and picture.index == 3
    assert protocol.parse_picture(json.loads(protocol.encode(picture))).name == "IMG_0001.JPG"


def test_no_camera_in_the_gear_list_means_no_picture(gear_dir: Path, tmp_path: Path) -> None:
    (gear_dir / "sensors.json").write_text(json.dumps({"GAS": {"CO2": "x"}}))
    gear = GearManager(gear_dir, lambda *a: None, pictures_dir=tmp_path)
    with pytest.raises(GearError, match="no camera"):
        gear.take_picture(FakeFlightController().state)


def test_heartbeats_follow_the_contract() -> None:
    fc = FakeFlightController()
    fc.set_battery(0.5)
    beat = build_heartbeat("D1", fc.state, protocol.MissionRef("m", "a", 2))
    parsed = protocol.parse_heartbeat(json.loads(protocol.encode(beat)))
    assert parsed.position.lat == pytest.approx(HOME[0])
    assert parsed.battery_remaining == 0.5 and parsed.mission.index == 2


def test_drone_id_from_the_mac_uses_its_last_three_bytes() -> None:
    assert derive_drone_id("REVOLUTION", bytes.fromhex("b827eb94e041")) == "REVOLUTION_94E041"
    assert protocol.is_drone_id(derive_drone_id())


def test_the_simulated_arming_line_is_two_characters(tmp_path: Path) -> None:
    line = SimulatedLine(tmp_path / "line")
    assert line.value == "00"
    line.request_arm()
    assert line.value == "10"
    line.request_disarm()
    assert line.value == "11"
    line.release()
    assert line.value == "00" and os.path.getsize(tmp_path / "line") == 2


def test_the_receiver_switch_sends_the_arming_sticks() -> None:
    fc = FakeFlightController()
    switch = UAVTalkReceiverSwitch(fc, rate_hz=50)
    arm = switch.channels("arm")
    assert arm[:6] == [1500, 1500, 1000, 2000, 1500, 1500] and len(arm) == 8
    switch.request_arm()
    assert wait_for(lambda: len([c for c in fc.calls if c[0] == "write"]) >= 4, 5)
    switch.release()
    writes = [c for c in fc.calls if c[0] == "write"]
    assert len(writes) >= 4
    assert writes[0][2]["Channel"] == arm
    assert writes[-1][2]["Channel"][3] == 1500  # released: yaw back to neutral


def test_the_bridge_relays_own_inputs_in_and_all_outputs_out() -> None:
    text = bridge_config("REVOLUTION_94E041", "mqtt://REVOLUTION_94E041:s3cret@ground:1883")
    lines = text.splitlines()
    assert "address ground:1883" in lines
    assert "remote_username REVOLUTION_94E041" in lines
    assert "remote_password s3cret" in lines
    assert "remote_clientid droneMosquitto-REVOLUTION_94E041" in lines
    assert (
        "notification_topic $SYS/broker/connection/droneMosquitto-REVOLUTION_94E041/state" in lines
    )
    assert "notifications_local_only true" in lines
    for channel in ("control", "mission", "gear"):
        assert f'topic REVOLUTION_94E041/{channel}/in in 1 "" ""' in lines
    outs = [line.split()[1] for line in lines if line.endswith('""') and " out " in line]
    assert outs == [
        f"+/{c}/out"
        for c in (
            "control",
            "mission",
            "gear",
            "heartbeats",
            "alarms",
            "telemetry",
            "camera",
            "pictures",
        )
    ]
    assert "listener 1884 127.0.0.1" in internal_broker_config(
        "D1", "mqtt://D1:p@g:1883", port=1884
    )
    with pytest.raises(ValueError):
        bridge_config("D1", "mqtt://g:1883")
    with pytest.raises(ValueError):
        bridge_config("D1", "mqtt://D1:p%0Aconnection%20evil@g:1883")


def test_launcher_accepts_every_credentials_shape() -> None:
    one = {
        "drone_id": "SIM_001",
        "mqtt": {"host": "10.0.0.1", "port": 1883, "username": "SIM_001", "password": "p@ss:w/rd"},
    }
    as_list = parse_credentials(json.dumps([one]))
    as_lines = parse_credentials(
        json.dumps(one) + "\n" + json.dumps(dict(one, drone_id="SIM_002")) + "\n"
    )
    as_map = parse_credentials(json.dumps({"SIM_001": one["mqtt"]}))
    assert as_list == as_map == as_lines[:1]
    assert [c.drone_id for c in as_lines] == ["SIM_001", "SIM_002"]
    url = broker_url_for(as_list[0], None)
    assert url == "mqtt://SIM_001:p%40ss%3Aw%2Frd@10.0.0.1:1883"
    from onboard.mqtt import parse_broker_url

    assert parse_broker_url(url).password == "p@ss:w/rd"
    assert broker_url_for(as_list[0], "mqtt://127.0.0.1:2883").endswith("@127.0.0.1:2883")


def test_launcher_spreads_drones_apart_around_home() -> None:
    from onboard.sensors import ground_distance

    points = spread(HOME, 6, 15.0)
    assert points[0][:2] == (round(HOME[0], 7), round(HOME[1], 7))
    for i, a in enumerate(points):
        for b in points[i + 1 :]:
            assert ground_distance(a[0], a[1], b[0], b[1]) > 10


def test_no_onboard_module_imports_django() -> None:
    package = Path(__file__).resolve().parents[2] / "onboard"
    offenders = []
    for path in package.rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [
                f"{path.name}: {n}"
                for n in names
                if n.split(".")[0] in ("django", "rest_framework", "channels", "celery")
            ]
    assert offenders == []


def test_the_receiver_switch_retries_after_the_board_refuses_to_arm() -> None:
    fc = FakeFlightController()
    switch = UAVTalkReceiverSwitch(fc, rate_hz=100)
    fc._state.update(arming=True)
    switch.request_arm()
    assert wait_for(lambda: len(fc.calls) >= 2, 5)  # the switch has seen Arming
    fc._state.update(arming=False)  # an alarm: back to Disarmed without arming
    assert wait_for(lambda: switch.retries == 1, 5)
    calls = len(fc.calls)
    assert wait_for(lambda: len(fc.calls) >= calls + 8, 5)  # neutral, then arm again
    switch.release()
    assert switch.retries == 1
    yaws = [c[2]["Channel"][3] for c in fc.calls if c[0] == "write"]
    # arm sticks, then neutral for a moment, then the arm sticks again
    first_neutral = yaws.index(1500)
    assert 2000 in yaws[:first_neutral] and 2000 in yaws[first_neutral:]

"""The UAVTalk driver against the simulator over a real pseudo-terminal."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from onboard.arming_frames import load_frames
from onboard.fc.base import CommandTimeout, FlightControllerError, NotConnected
from onboard.fc.uavtalk import UAVTalkFlightController
from onboard.links import LinkError, parse_link_url
from runtime.processes import wait_for

SCALE = 20.0
HOME = (38.736946, -9.142685, 100.0)
FRAMES = load_frames()


class LineSwitch:
    """The arming-switch contract on the simulator's line file (replaced atomically)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.set("00")

    def set(self, value: str) -> None:
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(value)
        os.replace(tmp, self.path)

    def request_arm(self) -> None:
        self.set("10")

    def request_disarm(self) -> None:
        self.set("11")

    def release(self) -> None:
        self.set("00")


@pytest.fixture
def line(tmp_path):
    return LineSwitch(tmp_path / "arming-line")


@pytest.fixture
def sim(line):
    process = start_simulator(home=HOME, time_scale=SCALE, arming_line=line.path)
    yield process
    process.stop()


@pytest.fixture
def fc(sim, line):
    driver = UAVTalkFlightController(sim.url, arming_switch=line, time_scale=SCALE)
    driver.start()
    assert driver.wait_connected(5)
    assert wait_for(lambda: driver.state.home is not None and driver.state.ned is not None, 3)
    yield driver
    driver.stop()


def test_link_urls_name_serial_ports_ptys_tcp_and_udp():
    assert parse_link_url("serial:/dev/ttyACM0?baud=57600").baud == 57600
    assert parse_link_url("serial:/dev/ttyACM0").path == "/dev/ttyACM0"
    assert parse_link_url("/dev/pts/5").path == "/dev/pts/5"
    tcp = parse_link_url("tcp://127.0.0.1:9000")
    assert (tcp.kind, tcp.host, tcp.port) == ("tcp", "127.0.0.1", 9000)
    udp = parse_link_url("udp://127.0.0.1:14550")
    assert (udp.kind, udp.port) == ("udp", 14550)
    with pytest.raises(LinkError):
        parse_link_url("udp://127.0.0.1")
    with pytest.raises(LinkError):
        parse_link_url("ftp://x:1")
    with pytest.raises(LinkError):
        parse_link_url("serial:/dev/ttyACM0?baud=fast")


def test_the_driver_connects_and_fills_the_vehicle_state(fc):
    state = fc.state
    assert state.connected and state.protocol == "uavtalk"
    assert state.home == pytest.approx(HOME, abs=1e-6)
    assert state.lat == pytest.approx(HOME[0], abs=1e-6)
    assert state.alt == pytest.approx(0.0, abs=0.01)
    assert wait_for(lambda: fc.state.quaternion is not None, 2)
    assert fc.state.quaternion[3] == pytest.approx(1.0, abs=1e-3)  # level: scalar part last
    assert wait_for(lambda: fc.state.battery_remaining is not None, 2)
    assert 0.99 < fc.state.battery_remaining <= 1.0
    assert fc.state.gps_fix and fc.state.satellites >= 7
    assert not fc.state.armed and fc.state.flight_mode == "Manual"


def test_requesting_an_object_returns_its_fields_with_enum_names(fc):
    status = fc.request_object("FlightStatus")
    assert status == {"Armed": "Disarmed", "FlightMode": "Manual", "ControlSource": "Transmitter"}


def test_an_unknown_object_is_nacked(fc):
    with pytest.raises(FlightControllerError, match="NACK"):
        fc.request_object_id(0x12345678, timeout=1.0)
    with pytest.raises(FlightControllerError, match="unknown UAVObject"):
        fc.request_object("NoSuchObject")


def test_listeners_receive_every_object_as_json_ready_fields(fc):
    seen: dict[str, dict] = {}
    fc.add_listener(lambda name, ts, fields: seen.setdefault(name, fields))
    assert wait_for(lambda: {"AttitudeActual", "GPSPosition", "PositionActual"} <= set(seen), 3)
    import json

    json.dumps(seen)  # plain values only
    assert seen["GPSPosition"]["Status"] == "Fix3D"


def test_arming_through_the_line_waits_for_flight_status_armed(fc, line):
    started = time.monotonic()
    fc.arm(timeout=5)
    elapsed = time.monotonic() - started
    assert fc.state.armed
    assert elapsed >= FRAMES.arming_time_s / SCALE * 0.9
    assert line.path.read_text() == "00"  # released once armed
    fc.disarm(timeout=5)
    assert not fc.state.armed


def test_holding_the_line_by_hand_arms_after_the_arming_time(fc, line):
    line.set("10")
    time.sleep(FRAMES.arming_time_s / SCALE * 0.5)
    assert not fc.state.armed
    assert wait_for(lambda: fc.state.armed, 2)
    line.set("00")


def test_arming_without_a_switch_is_refused(sim):
    driver = UAVTalkFlightController(sim.url, time_scale=SCALE)
    driver.start()
    try:
        assert driver.wait_connected(5)
        with pytest.raises(FlightControllerError, match="arming switch"):
            driver.arm(timeout=0.5)
    finally:
        driver.stop()


def test_arming_through_uavtalk_receiver_channels(fc):
    # The UAVTalkReceiver backend's job, done here at 10 Hz with the driver's own writes.
    stop = threading.Event()
    neutral = [FRAMES.to_channel_period_us(FRAMES.pulse_neutral_us)] * 8
    arm = [FRAMES.to_channel_period_us(p) for p in FRAMES.arm_frame_us] + neutral[:2]

    def sticks() -> None:
        while not stop.is_set():
            fc.write_object("UAVTalkReceiver", {"Channel": arm, "RSSI": 65535})
            stop.wait(0.1)

    thread = threading.Thread(target=sticks, daemon=True)
    thread.start()
    try:
        assert wait_for(lambda: fc.state.armed, 3)
    finally:
        stop.set()
        thread.join()


def test_take_off_fly_north_and_land_converge_on_the_target(fc):
    fc.arm(timeout=5)
    fc.takeoff(10)
    assert wait_for(lambda: abs(fc.state.alt - 10) < 0.5, 8)
    assert fc.state.flight_mode == "PathPlanner"
    fc.goto_ned(100, 0, -10)
    furthest = 0.0

    def arrived() -> bool:
        nonlocal furthest
        furthest = max(furthest, fc.state.ned[0])
        return abs(fc.state.ned[0] - 100) < 1.0

    assert wait_for(arrived, 8)
    assert furthest <= 100.5
    assert fc.state.lat > HOME[0]
    path = fc.request_object("PathDesired")
    assert path["End"] == [100.0, 0.0, -10.0] and path["Mode"] == "Endpoint"
    fc.land()
    assert wait_for(lambda: fc.state.alt < 0.05, 10)
    assert fc.state.ned[0] == pytest.approx(100, abs=1.0)
    fc.disarm(timeout=5)


def test_disarming_in_the_air_times_out(fc):
    fc.arm(timeout=5)
    fc.takeoff(5)
    assert wait_for(lambda: fc.state.alt > 4, 8)
    with pytest.raises(CommandTimeout):
        fc.disarm(timeout=FRAMES.disarming_time_s / SCALE * 3)
    assert fc.state.armed


def test_reset_reboots_the_board_disarmed_keeping_home(fc):
    fc.arm(timeout=5)
    handshakes = fc.stats["handshakes"]
    fc.reset()
    assert wait_for(lambda: fc.stats["handshakes"] > handshakes and fc.state.connected, 5)
    assert wait_for(lambda: fc.request_object("FlightStatus")["Armed"] == "Disarmed", 2)
    assert fc.request_object("HomeLocation")["Set"] == "TRUE"
    assert fc.state.home == pytest.approx(HOME, abs=1e-6)


def test_rebuild_link_opens_a_new_session(fc):
    handshakes = fc.stats["handshakes"]
    fc.rebuild_link()
    assert wait_for(lambda: fc.stats["handshakes"] == handshakes + 1 and fc.state.connected, 5)
    assert fc.link.generation == 2
    assert fc.request_object("FlightStatus")["Armed"] == "Disarmed"


def test_the_driver_reconnects_after_the_simulator_restarts(tmp_path):
    link = tmp_path / "fc-tty"
    first = start_simulator(home=HOME, time_scale=SCALE, pty_link=link)
    driver = UAVTalkFlightController(f"serial:{link}", time_scale=SCALE)
    driver.start()
    try:
        assert driver.wait_connected(5)
        first.stop()
        assert wait_for(lambda: not driver.state.connected, 3)
        with pytest.raises(NotConnected):
            driver.request_object("FlightStatus", timeout=0.5)
        second = start_simulator(home=HOME, time_scale=SCALE, pty_link=link)
        try:
            assert driver.wait_connected(5)
            assert driver.request_object("FlightStatus")["Armed"] == "Disarmed"
            assert driver.stats["link_drops"] >= 1
        finally:
            second.stop()
    finally:
        driver.stop()


def test_the_driver_works_over_tcp():
    sim = start_simulator(home=HOME, time_scale=SCALE, tcp_port=0)
    driver = UAVTalkFlightController(sim.url, time_scale=SCALE)
    driver.start()
    try:
        assert driver.wait_connected(5)
        assert driver.request_object("HomeLocation")["Set"] == "TRUE"
    finally:
        driver.stop()
        sim.stop()


def test_a_second_session_on_the_same_port_is_refused(fc, sim):
    other = UAVTalkFlightController(sim.url, time_scale=SCALE)
    other.start()
    try:
        assert not other.wait_connected(1.0)
        assert fc.state.connected
    finally:
        other.stop()

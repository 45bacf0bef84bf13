"""The drone's wind rule (onboard/wind.py): the gear's limit, the flight controller's
estimate as each autopilot sends it, the take-off guard and the return after the stated
time; and the simulator's wind (firmware/sim/wind.py)."""

from __future__ import annotations

import json
import math
import struct
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim import start_simulator
from firmware.sim.vehicle import Vehicle
from firmware.sim.wind import WindError, parse_wind, wind_ned, write_wind
from onboard.fc.base import VehicleState
from onboard.fc.mavlink import MavlinkCodec, MavlinkFlightController
from onboard.gear import GearManager
from onboard.uavtalk import ObjectRegistry
from onboard.uavtalk.crc import crc8
from onboard.uavtalk.frames import FrameDecoder
from onboard.wind import (
    DEFAULT_MAX_WIND_M_S,
    OBJECT,
    WindLimitError,
    WindWatch,
    limit_from_specs,
    parse_limit,
    wind_from_object,
)
from tests.onboard.mavlink.conftest import HOME, TIME_SCALE, Recorder, wait_for

ON_GROUND = VehicleState(armed=False, alt=0.0)
FLYING = VehicleState(armed=True, alt=10.0)


@pytest.mark.parametrize("value", [-3, 0, float("nan"), True, "12", 41])
def test_a_malformed_limit_is_refused_naming_the_field(value):
    with pytest.raises(WindLimitError, match="MAX_WIND_M_S"):
        parse_limit(value)


def test_the_limit_is_the_gears_else_the_default():
    assert limit_from_specs({"MAX_WIND_M_S": 12}) == 12.0
    assert limit_from_specs({"TYPE": "HEXACOPTER"}) == DEFAULT_MAX_WIND_M_S
    assert limit_from_specs(None) == DEFAULT_MAX_WIND_M_S


def test_gear_specs_with_a_negative_limit_are_refused_and_the_last_good_ones_stay(tmp_path):
    (tmp_path / "specs.json").write_text(json.dumps({"MAX_WIND_M_S": 12}))
    gear = GearManager(tmp_path, lambda channel, message: None)
    assert gear.specs == {"MAX_WIND_M_S": 12}
    (tmp_path / "specs.json").write_text(json.dumps({"MAX_WIND_M_S": -5}))
    assert gear.reload() is False
    assert gear.specs == {"MAX_WIND_M_S": 12}
    assert gear.errors == 1


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def watch(limit: float = 10.0, hold_s: float = 10.0) -> tuple[WindWatch, Clock, list[str]]:
    clock, returns = Clock(), []

    def return_home(reason: str) -> str:
        returns.append(reason)
        return "return"

    return WindWatch(lambda: limit, return_home, hold_s=hold_s, clock=clock), clock, returns


def blow(w: WindWatch, north: float, east: float) -> None:
    w.on_object(OBJECT, 0.0, {"North": north, "East": east, "Down": 0.0, "Source": "WIND"})


def test_take_off_is_refused_above_the_limit_with_the_figure():
    w, _, _ = watch(limit=10.0)
    assert w.guard("takeoff", "takeoff", (0, 0, -10), ON_GROUND) is None  # no estimate
    blow(w, 9.0, 6.0)  # 10.8 m/s
    refusal = w.guard("takeoff", "takeoff", (0, 0, -10), ON_GROUND)
    assert refusal is not None and "10.8 m/s" in refusal and "limit of 10 m/s" in refusal
    # Moves in the air and landing are the fail-safe's business, not the guard's.
    assert w.guard("navigate", "goto", (50, 0, -10), FLYING) is None
    assert w.guard("land", "land", (0, 0, 0), FLYING) is None
    blow(w, 6.0, 6.0)  # 8.5 m/s
    assert w.guard("takeoff", "takeoff", (0, 0, -10), ON_GROUND) is None


def test_in_flight_the_drone_returns_once_the_wind_stayed_above_the_limit():
    w, clock, returns = watch(limit=10.0, hold_s=10.0)
    blow(w, 0.0, 12.0)
    assert w.tick(FLYING) is None
    clock.now += 6
    blow(w, 0.0, 9.0)  # a lull: the count starts again
    assert w.tick(FLYING) is None
    blow(w, 0.0, 12.0)
    assert w.tick(FLYING) is None
    clock.now += 9.5
    blow(w, 0.0, 12.0)
    assert w.tick(FLYING) is None and returns == []
    clock.now += 1
    blow(w, 0.0, 12.0)
    assert w.tick(FLYING) == "return"
    assert "wind 12.0 m/s above the limit of 10 m/s" in returns[0]
    report = w.report()
    assert report["action"] == "return" and report["speed"] == 12.0 and report["limit"] == 10
    clock.now += 1
    assert w.tick(FLYING) is None and len(returns) == 1  # once per flight
    # Landed and disarmed: the next flight starts afresh.
    w.tick(VehicleState(armed=False, alt=0.0))
    assert "action" not in w.report()


def test_below_the_limit_nothing_happens_and_a_stale_estimate_is_unknown():
    w, clock, returns = watch(limit=10.0, hold_s=0.5)
    blow(w, 5.0, 5.0)
    clock.now += 60
    assert w.tick(FLYING) is None and returns == []
    assert w.current() is None and w.report() is None


def test_nan_components_are_no_estimate():
    assert wind_from_object({"North": math.nan, "East": 1.0, "Down": 0.0}) is None
    assert wind_from_object({"North": 1.0}) is None


# -- the simulator and the MAVLink driver -------------------------------------------------


def test_sim_wind_text():
    assert parse_wind("12,270") == (12.0, 270.0)
    with pytest.raises(WindError):
        parse_wind("-1,0")
    with pytest.raises(WindError):
        parse_wind("twelve")
    north, east, _ = wind_ned(10.0, 270.0)  # from the west: the air moves east
    assert abs(north) < 1e-9 and east == pytest.approx(10.0)


def test_the_simulated_vehicle_drifts_a_little_downwind():
    calm, windy = Vehicle(), Vehicle()
    windy.wind = wind_ned(12.0, 0.0)  # from the north: pushed south
    for v in (calm, windy):
        v.receiver.state = "Armed"
        v.flight_mode = "PositionHold"
        v.set_path_desired("HoldPosition", (0.0, 0.0, -10.0))
        for _ in range(400):
            v.step(0.05)
    assert calm.ned[0] == pytest.approx(0.0, abs=1e-6)
    assert -2.0 < windy.ned[0] < -0.01


def test_the_wire_form_each_autopilot_uses_decodes_to_the_platform_object():
    """WIND_COV and WIND frames written by pymavlink's own encoder."""
    codec = MavlinkCodec(1, 1)
    cov = mavlink.MAVLink_wind_cov_message(0, 1.5, -2.0, 0.1, 0.5, 0.2, 112.0, 0.0, 0.0)
    ardu = mavlink.MAVLink_wind_message(90.0, 8.0, 0.0)  # from the east: moves west
    wire = cov.pack(mavlink.MAVLink(None, 1, 1)) + ardu.pack(mavlink.MAVLink(None, 1, 1))
    messages = codec.feed(wire)
    assert [m.get_type() for m in messages] == ["WIND_COV", "WIND"]
    from onboard.fc.mavlink import _PLATFORM_OBJECTS

    ((name, fields),) = _PLATFORM_OBJECTS["WIND_COV"](messages[0])
    assert name == OBJECT and fields["North"] == 1.5 and fields["East"] == -2.0
    ((name, fields),) = _PLATFORM_OBJECTS["WIND"](messages[1])
    assert fields["North"] == pytest.approx(0.0, abs=1e-6)
    assert fields["East"] == pytest.approx(-8.0)


@pytest.mark.parametrize(("autopilot", "message"), [("px4", "WIND_COV"), ("ardupilot", "WIND")])
def test_each_simulated_autopilot_reports_its_wind_and_a_change_in_flight(
    tmp_path, autopilot, message
):
    wind_file = tmp_path / "wind"
    write_wind(wind_file, 12.0, 270.0)
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--autopilot", autopilot, "--wind-file", str(wind_file)],
        log_file=tmp_path / "sim.log",
    )
    recorder = Recorder()
    fc = MavlinkFlightController(sim.link_url)
    fc.add_listener(recorder)
    fc.start()
    try:
        assert fc.wait_connected(5)
        assert wait_for(lambda: recorder.counts[OBJECT] > 0, 10)
        assert recorder.counts[message] > 0
        other = "WIND" if message == "WIND_COV" else "WIND_COV"
        assert recorder.counts[other] == 0  # each autopilot sends only its own
        wind = recorder.last[OBJECT]
        assert wind["Source"] == message
        assert wind["North"] == pytest.approx(0.0, abs=0.01)
        assert wind["East"] == pytest.approx(12.0, abs=0.01)
        time.sleep(0.05)  # a new mtime
        write_wind(wind_file, 4.0, 0.0)
        assert wait_for(lambda: abs(recorder.last[OBJECT]["North"] + 4.0) < 0.01, 10)
    finally:
        fc.stop()
        sim.stop()


def test_a_dronin_board_sending_windvelocityactual_gives_the_wind():
    """dRonin defines WindVelocityActual (no flight module of its firmware writes it); a
    board that sends one is read: a frame laid out byte by byte as docs/uavtalk.md says."""
    payload = struct.pack("<3f", 3.0, -4.0, 0.5)  # North, East, Down in m/s
    header = struct.pack("<BBHI", 0x3C, 0x20, 8 + len(payload), 0x6D31D2F8)
    frame = header + payload
    frame += bytes([crc8(frame)])
    (decoded,) = FrameDecoder(ObjectRegistry.load()).feed(frame)
    assert decoded.obj.name == OBJECT
    w, _, _ = watch(limit=4.0)
    w.on_object(OBJECT, 0.0, decoded.fields())
    assert w.current().speed == pytest.approx(5.0)
    assert "5.0 m/s" in w.guard("takeoff", "takeoff", (0, 0, -10), ON_GROUND)


@pytest.mark.parametrize("fc", ["uavtalk", "mavlink"])
def test_the_simulators_launch_wind_reaches_its_vehicle(fc, tmp_path):
    from firmware.sim.__main__ import _session, apply_wind, build_parser

    wind_file = tmp_path / "wind"
    args = build_parser().parse_args(["--fc", fc, "--wind", "10,90", "--wind-file", str(wind_file)])
    session = _session(args)
    apply_wind(session, args)
    if fc == "mavlink":
        assert (session.params["SIM_WIND_SPD"], session.params["SIM_WIND_DIR"]) == (10.0, 90.0)
        session.tick(0.0)
    north, east, _ = session.vehicle.wind  # from the east: the air moves west
    assert north == pytest.approx(0.0, abs=1e-9) and east == pytest.approx(-10.0)
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--wind", "-3,0"])

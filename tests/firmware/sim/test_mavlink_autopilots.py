"""The simulator's PX4 and ArduPilot personalities refuse what the real autopilots refuse.

Sans-I/O: a ground station's messages go straight into `MavlinkSession.receive` and the
clock is the test's, so every precondition is checked exactly, without sockets.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim.mavlink_server import MavlinkSession
from firmware.sim.mavlink_streams import AUTOPILOT_ONLY, STREAMED
from firmware.sim.remote_id import RemoteIdModule
from firmware.sim.vehicle import Vehicle, VehicleConfig
from onboard.fc.mavlink import MavlinkCodec
from onboard.navigation import ned_to_lla

HOME = (40.6303, -8.6575, 12.0)
STEP_S = 0.05
CUSTOM = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


class Ground:
    """A ground station on the session's input, with the session's clock in its hands."""

    def __init__(self, autopilot: str, **params: float) -> None:
        self.session = MavlinkSession(
            vehicle=Vehicle(config=VehicleConfig(home=HOME)), autopilot=autopilot
        )
        self.session.params.update(params)
        self.codec = MavlinkCodec(255, mavlink.MAV_COMP_ID_MISSIONPLANNER)
        self.now = 100.0
        self.inbox: list[Any] = []
        self.send("heartbeat", mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        self.run(0.1)

    @property
    def vehicle(self) -> Vehicle:
        return self.session.vehicle

    def send(self, name: str, *args: Any) -> None:
        self.session.receive(self.codec.encode(name, *args), self.now)
        self._collect()

    def _collect(self) -> None:
        self.inbox += self.session.codec.feed(b"") or []
        self.inbox += self.codec.feed(self.session.take_output())

    def run(self, seconds: float, *, setpoint: tuple[float, float, float] | None = None) -> None:
        """Let `seconds` pass; with `setpoint`, stream it at 20 Hz meanwhile (LOCAL_NED)."""
        for _ in range(round(seconds / STEP_S)):
            self.now += STEP_S
            if setpoint is not None:
                self.send(
                    "set_position_target_local_ned",
                    0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, 0x0FF8, *setpoint, *([0.0] * 8),
                )  # fmt: skip
            self.session.tick(self.now)
            self._collect()

    def command(self, command: int, *params: float) -> int:
        """COMMAND_LONG; returns the COMMAND_ACK result."""
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        self.inbox.clear()
        self.send("command_long", 1, 1, command, 0, *values)
        acks = [m for m in self.inbox if m.get_type() == "COMMAND_ACK" and m.command == command]
        assert len(acks) == 1, self.inbox
        return acks[0].result

    def texts(self) -> list[str]:
        return [m.text for m in self.inbox if m.get_type() == "STATUSTEXT"]

    def arm(self) -> int:
        return self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)

    def px4_mode(self, main: int, sub: int = 0) -> int:
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, CUSTOM, main, sub)

    def copter_mode(self, name: str) -> int:
        number = {"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, CUSTOM, number[name])

    def upload(self, items: list[tuple[int, float, float, float]]) -> int:
        """The mission protocol from the ground's side; returns the MISSION_ACK type."""
        self.inbox.clear()
        self.send("mission_count", 1, 1, len(items), 0)
        for seq, (command, lat, lon, alt) in enumerate(items):
            frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            x, y = round(lat * 1e7), round(lon * 1e7)
            self.send("mission_item_int", 1, 1, seq, frame, command, 0, 1, 0, 0, 0, 0, x, y, alt, 0)
        acks = [m for m in self.inbox if m.get_type() == "MISSION_ACK"]
        return acks[-1].type

    def fly_up(self, altitude: float) -> None:
        assert self.arm() == mavlink.MAV_RESULT_ACCEPTED
        if self.session.px4:
            result = self.command(mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, math.nan, math.nan, math.nan, HOME[2] + altitude)  # fmt: skip
        else:
            assert self.copter_mode("GUIDED") == mavlink.MAV_RESULT_ACCEPTED
            result = self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude)
        assert result == mavlink.MAV_RESULT_ACCEPTED
        self.run(altitude / 2 + 3)
        assert -self.vehicle.ned[2] == pytest.approx(altitude, abs=0.3)


def lla(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_lla(north, east, 0.0, HOME)
    return lat, lon


# --- PX4 -----------------------------------------------------------------------------------


def test_px4_enters_offboard_only_on_a_setpoint_stream_already_running():
    ground = Ground("px4")
    ground.fly_up(10.0)
    # No stream: refused, and the hold goes on.
    assert ground.px4_mode(6) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert any("no setpoint stream" in t for t in ground.texts())
    # A stream that starts with the switch is not enough: PX4 wants a second of it first.
    ground.run(0.3, setpoint=(0.0, 0.0, -10.0))
    assert ground.px4_mode(6) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    ground.run(1.0, setpoint=(0.0, 0.0, -10.0))
    assert ground.px4_mode(6) == mavlink.MAV_RESULT_ACCEPTED
    assert ground.session.mode == "OFFBOARD"
    ground.run(8.0, setpoint=(15.0, -5.0, -12.0))
    assert ground.vehicle.ned == pytest.approx([15.0, -5.0, -12.0], abs=0.2)


def test_px4_leaves_offboard_for_hold_when_the_stream_stops():
    ground = Ground("px4")
    ground.fly_up(10.0)
    ground.run(1.5, setpoint=(0.0, 0.0, -10.0))
    assert ground.px4_mode(6) == mavlink.MAV_RESULT_ACCEPTED
    ground.run(0.5, setpoint=(40.0, 0.0, -10.0))
    ground.inbox.clear()
    ground.run(1.5)  # silence longer than COM_OF_LOSS_T (1 s)
    assert ground.session.mode == "GUIDED"  # PX4's hold (AUTO.LOITER)
    assert any("offboard signal lost" in t for t in ground.texts())
    north = ground.vehicle.ned[0]
    ground.run(5.0)
    assert north < 40.0 - 5 and ground.vehicle.ned[0] == pytest.approx(north, abs=6.0)


def test_px4_ignores_setpoints_outside_offboard_and_repositions_in_hold():
    ground = Ground("px4")
    ground.fly_up(10.0)
    ground.run(3.0, setpoint=(30.0, 0.0, -10.0))
    assert ground.vehicle.ned[:2] == pytest.approx([0.0, 0.0], abs=0.1)
    assert ground.session.stats.setpoints_ignored > 0
    lat, lon = lla(30.0, 10.0)
    ground.inbox.clear()
    ground.send(
        "command_int", 1, 1, mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_CMD_DO_REPOSITION, 0, 0,
        -1, mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, math.nan,
        round(lat * 1e7), round(lon * 1e7), HOME[2] + 14.0,
    )  # fmt: skip
    ack = next(m for m in ground.inbox if m.get_type() == "COMMAND_ACK")
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED
    ground.run(10.0)
    assert ground.vehicle.ned == pytest.approx([30.0, 10.0, -14.0], abs=0.3)


def test_px4_refuses_arming_and_takeoff_without_a_global_position():
    ground = Ground("px4", SIM_GPS_DISABLE=1)
    takeoff = ground.command(mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, math.nan, math.nan, math.nan, HOME[2] + 10)  # fmt: skip
    assert takeoff == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert "Takeoff denied! Please disarm and retry" in ground.texts()
    assert ground.px4_mode(4, 3) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED  # Hold
    ground.session.set_mode("GUIDED")  # already in Hold when the fix went away
    assert ground.arm() == mavlink.MAV_RESULT_DENIED
    assert any("Arming denied" in t and "global position" in t for t in ground.texts())
    assert not ground.session.armed


def test_px4_takeoff_while_disarmed_waits_in_takeoff_mode_until_armed():
    ground = Ground("px4", MIS_TAKEOFF_ALT=7.0)
    nan = math.nan
    assert ground.command(mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, nan, nan, nan, nan) == 0
    assert ground.session.mode == "TAKEOFF"
    ground.run(2.0)
    assert ground.vehicle.ned[2] == 0.0  # disarmed: nothing turns
    assert ground.arm() == mavlink.MAV_RESULT_ACCEPTED
    ground.run(8.0)
    assert -ground.vehicle.ned[2] == pytest.approx(7.0, abs=0.2)  # MIS_TAKEOFF_ALT
    assert ground.session.mode == "GUIDED"  # then holds, as PX4 does after Takeoff


def test_px4_starts_a_mission_only_when_it_has_one_and_arms_for_it():
    ground = Ground("px4")
    assert ground.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == mavlink.MAV_RESULT_DENIED
    assert any("no valid mission" in t for t in ground.texts())
    assert ground.px4_mode(4, 4) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    there = lla(20.0, 0.0)
    items = [(mavlink.MAV_CMD_NAV_TAKEOFF, *lla(0, 0), 8.0)]
    items += [(mavlink.MAV_CMD_NAV_WAYPOINT, *there, 8.0), (mavlink.MAV_CMD_NAV_LAND, *there, 0)]
    assert ground.upload(items) == mavlink.MAV_MISSION_ACCEPTED
    assert ground.command(mavlink.MAV_CMD_MISSION_START, 0, 2) == mavlink.MAV_RESULT_ACCEPTED
    assert ground.session.armed and ground.session.mode == "AUTO"  # PX4 arms on the start
    ground.inbox.clear()
    ground.run(25.0)
    reached = [m.seq for m in ground.inbox if m.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [0, 1, 2]  # PX4 flies from item 0: no home item
    assert not ground.session.armed
    assert ground.vehicle.ned == pytest.approx([20.0, 0.0, 0.0], abs=0.3)


def test_px4_return_climbs_to_rtl_return_alt_flies_home_lands_and_disarms():
    ground = Ground("px4", RTL_RETURN_ALT=25.0)
    ground.fly_up(10.0)
    ground.session.vehicle.set_path_desired("Endpoint", (40.0, 0.0, -10.0))
    ground.run(10.0)
    assert ground.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH) == mavlink.MAV_RESULT_ACCEPTED
    highest = 0.0
    for _ in range(60):
        ground.run(1.0)
        highest = min(highest, ground.vehicle.ned[2])
    assert highest == pytest.approx(-25.0, abs=0.3)
    assert ground.vehicle.ned == pytest.approx([0.0, 0.0, 0.0], abs=0.3)
    assert not ground.session.armed


# --- ArduPilot -----------------------------------------------------------------------------


def test_ardupilot_takes_off_only_in_guided_and_armed():
    ground = Ground("ardupilot")
    takeoff = (mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10.0)
    assert ground.command(*takeoff) == mavlink.MAV_RESULT_FAILED  # disarmed, STABILIZE
    assert ground.arm() == mavlink.MAV_RESULT_ACCEPTED
    assert ground.command(*takeoff) == mavlink.MAV_RESULT_FAILED  # armed, not GUIDED
    assert ground.copter_mode("GUIDED") == mavlink.MAV_RESULT_ACCEPTED
    assert ground.command(*takeoff) == mavlink.MAV_RESULT_ACCEPTED


def test_ardupilot_flies_setpoints_only_in_guided():
    ground = Ground("ardupilot")
    ground.fly_up(10.0)
    assert ground.copter_mode("LOITER") == mavlink.MAV_RESULT_ACCEPTED
    lat, lon = lla(25.0, 0.0)

    def setpoint() -> None:
        ground.send(
            "set_position_target_global_int", 0, 1, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            0x0FF8, round(lat * 1e7), round(lon * 1e7), 10.0, *([0.0] * 8),
        )  # fmt: skip

    setpoint()
    ground.run(5.0)
    assert ground.vehicle.ned[0] == pytest.approx(0.0, abs=0.1)
    assert ground.copter_mode("GUIDED") == mavlink.MAV_RESULT_ACCEPTED
    setpoint()
    ground.run(8.0)
    assert ground.vehicle.ned[0] == pytest.approx(25.0, abs=0.3)


def test_ardupilot_will_not_arm_in_auto_nor_enter_auto_without_a_usable_mission():
    ground = Ground("ardupilot")
    assert ground.copter_mode("AUTO") == mavlink.MAV_RESULT_FAILED  # no mission at all
    there = lla(20.0, 0.0)
    home = (mavlink.MAV_CMD_NAV_WAYPOINT, *lla(0, 0), 0.0)
    assert ground.upload([home, (mavlink.MAV_CMD_NAV_WAYPOINT, *there, 8.0)]) == 0
    assert ground.copter_mode("AUTO") == mavlink.MAV_RESULT_ACCEPTED  # disarmed: allowed
    assert ground.arm() == mavlink.MAV_RESULT_DENIED
    assert "Arm: Mode AUTO not armable" in ground.texts()
    assert ground.copter_mode("GUIDED") == mavlink.MAV_RESULT_ACCEPTED
    assert ground.arm() == mavlink.MAV_RESULT_ACCEPTED
    # Armed on the ground, AUTO must begin with a take-off (item 1: item 0 is home).
    assert ground.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == mavlink.MAV_RESULT_FAILED
    assert "Auto: Missing Takeoff Cmd" in ground.texts()
    assert ground.session.mode == "GUIDED"


def test_ardupilot_keeps_home_in_item_zero_and_flies_from_item_one():
    ground = Ground("ardupilot")
    there = lla(20.0, 0.0)
    items = [
        (mavlink.MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 99.0),  # in item 0: what a driver without
        (mavlink.MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 8.0),  # the home slot would lose
        (mavlink.MAV_CMD_NAV_WAYPOINT, *there, 8.0),
        (mavlink.MAV_CMD_NAV_LAND, *there, 0.0),
    ]
    assert ground.upload(items) == mavlink.MAV_MISSION_ACCEPTED
    ground.inbox.clear()
    ground.send("mission_request_int", 1, 1, 0, 0)
    home = next(m for m in ground.inbox if m.get_type() == "MISSION_ITEM_INT")
    assert (home.x, home.y, home.z) == (round(HOME[0] * 1e7), round(HOME[1] * 1e7), HOME[2])
    assert ground.copter_mode("GUIDED") == mavlink.MAV_RESULT_ACCEPTED
    assert ground.arm() == mavlink.MAV_RESULT_ACCEPTED
    assert ground.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == mavlink.MAV_RESULT_ACCEPTED
    ground.inbox.clear()
    highest = 0.0
    for _ in range(30):
        ground.run(1.0)
        highest = min(highest, ground.vehicle.ned[2])
    reached = [m.seq for m in ground.inbox if m.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [1, 2, 3]
    assert highest == pytest.approx(-8.0, abs=0.3)  # never the 99 m of item 0
    assert not ground.session.armed


def test_both_autopilots_refuse_position_modes_without_a_fix():
    ardupilot = Ground("ardupilot", SIM_GPS_DISABLE=1)
    assert ardupilot.copter_mode("GUIDED") == mavlink.MAV_RESULT_FAILED
    assert "Mode change to GUIDED failed: requires position" in ardupilot.texts()
    assert ardupilot.arm() == mavlink.MAV_RESULT_ACCEPTED  # STABILIZE needs no fix
    px4 = Ground("px4", SIM_GPS_DISABLE=1)
    assert px4.px4_mode(4, 5) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED  # Return
    healthy = [m for m in px4.inbox if m.get_type() == "SYS_STATUS"]
    px4.run(1.5)
    healthy = [m for m in px4.inbox if m.get_type() == "SYS_STATUS"]
    assert healthy and not healthy[-1].onboard_control_sensors_health & 0x20  # GPS unhealthy
    assert not [m for m in px4.inbox if m.get_type() == "GLOBAL_POSITION_INT"]


def test_px4_streams_unasked_and_describes_itself_in_autopilot_version():
    ground = Ground("px4")
    ground.run(2.5)
    kinds = {m.get_type() for m in ground.inbox}
    assert {"SYS_STATUS", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT", "HOME_POSITION"} <= kinds
    assert ground.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == 0  # fmt: skip
    version = next(m for m in ground.inbox if m.get_type() == "AUTOPILOT_VERSION")
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    assert version.flight_sw_version >> 24 == 1  # PX4 v1.x
    quiet = Ground("ardupilot")
    quiet.run(2.5)
    assert not {"SYS_STATUS", "GLOBAL_POSITION_INT"} & {m.get_type() for m in quiet.inbox}


@pytest.mark.parametrize("name", sorted(STREAMED))
def test_every_message_in_the_stream_table_answers_a_request_for_it(name):
    ground = Ground(AUTOPILOT_ONLY.get(name, "ardupilot"))
    if name == "OPEN_DRONE_ID_ARM_STATUS":
        ground.session.remote_id = RemoteIdModule()  # the Remote ID module's own message
    if name == "SMART_BATTERY_INFO":
        ground.session.battery_serial = "SIMPACK-1"  # a smart battery's own message
    ground.inbox.clear()
    message_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
    assert ground.command(mavlink.MAV_CMD_REQUEST_MESSAGE, message_id) == 0
    assert name in {m.get_type() for m in ground.inbox}


def test_a_message_outside_the_stream_table_is_refused_not_sent():
    ground = Ground("ardupilot")
    result = ground.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_VFR_HUD)
    assert result == mavlink.MAV_RESULT_UNSUPPORTED
    assert "VFR_HUD" not in {m.get_type() for m in ground.inbox}


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_mission_uploaded_in_flight_replaces_the_running_one(autopilot):
    ground = Ground(autopilot)
    ground.fly_up(10.0)
    home = [(mavlink.MAV_CMD_NAV_WAYPOINT, *lla(0, 0), 0.0)] if autopilot == "ardupilot" else []
    far = [(mavlink.MAV_CMD_NAV_WAYPOINT, *lla(300.0, 0.0), 10.0)]
    assert ground.upload(home + far) == mavlink.MAV_MISSION_ACCEPTED
    assert ground.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == mavlink.MAV_RESULT_ACCEPTED
    ground.run(5.0)
    assert 5.0 < ground.vehicle.ned[0] < 100.0
    near = [(mavlink.MAV_CMD_NAV_WAYPOINT, *lla(0.0, 30.0), 10.0)]
    assert ground.upload(home + near) == mavlink.MAV_MISSION_ACCEPTED
    ground.run(25.0)
    assert ground.session.mode == "AUTO"
    assert ground.vehicle.ned == pytest.approx([0.0, 30.0, -10.0], abs=1.0)  # acceptance radius

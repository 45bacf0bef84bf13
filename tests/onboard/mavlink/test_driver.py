"""The MAVLink driver against the simulator's MAVLink personality over real TCP sockets."""

from __future__ import annotations

import os
import signal
import socket
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim import start_simulator
from onboard.fc.base import CommandTimeout
from onboard.fc.mavlink import (
    DATA_STREAMS,
    CommandRejected,
    MavlinkCodec,
    MavlinkFlightController,
)
from onboard.navigation import lla_to_ned

from .conftest import HOME, TIME_SCALE, wait_for


def fly_up(fc: MavlinkFlightController, altitude: float = 10.0) -> None:
    fc.arm(timeout=5)
    fc.takeoff(altitude)
    assert wait_for(lambda: abs((fc.state.alt or 0) - altitude) < 0.3, 10)


def test_the_driver_arms_takes_off_flies_to_a_coordinate_and_lands(fc):
    fc.arm(timeout=5)
    assert fc.state.armed
    assert fc.state.flight_mode == "STABILIZE"
    fc.takeoff(12.0)
    assert fc.state.flight_mode == "GUIDED"
    assert wait_for(lambda: abs(fc.state.alt - 12.0) < 0.2, 10), fc.state
    target_lat, target_lon = HOME[0] + 0.0004, HOME[1] + 0.0003
    north, east, _ = lla_to_ned(target_lat, target_lon, 0.0, fc.state.home)
    fc.goto_ned(north, east, -15.0)
    assert wait_for(
        lambda: (
            abs(fc.state.lat - target_lat) < 2e-6
            and abs(fc.state.lon - target_lon) < 2e-6
            and abs(fc.state.alt - 15.0) < 0.2
        ),
        15,
    ), fc.state
    fc.land()
    assert wait_for(lambda: not fc.state.armed, 15), fc.state
    assert fc.state.alt == pytest.approx(0.0, abs=0.05)
    assert fc.state.flight_mode == "LAND"
    fc.arm(timeout=5)  # ArduCopter will not arm in LAND: the driver switches to GUIDED
    assert fc.state.armed and fc.state.flight_mode == "GUIDED"


def test_a_disarm_in_the_air_is_refused_with_the_mavlink_result_named(fc):
    fly_up(fc)
    with pytest.raises(CommandRejected) as refused:
        fc.disarm(timeout=3, force=False)
    assert refused.value.result_name == "MAV_RESULT_DENIED"
    assert "MAV_RESULT_DENIED" in str(refused.value)
    assert "flying" in str(refused.value)
    assert fc.state.armed
    fc.disarm(timeout=3, force=True)
    assert not fc.state.armed


def test_arming_with_a_critical_battery_is_denied_and_the_statustext_says_why(fc, recorder):
    assert fc.set_param("BATT_CRT_PCT", 100.0) == 100.0
    with pytest.raises(CommandRejected) as refused:
        fc.arm(timeout=3)
    assert "MAV_RESULT_DENIED" in str(refused.value)
    assert "Battery critical" in str(refused.value)
    assert not fc.state.armed
    assert wait_for(lambda: "STATUSTEXT" in recorder.last, 2)
    assert "Battery critical" in recorder.last["STATUSTEXT"]["text"]


def test_a_command_the_vehicle_never_answers_ends_in_a_timeout_and_the_link_survives(fc):
    fc.set_param("SIM_CMD_MUTE", float(mavlink.MAV_CMD_COMPONENT_ARM_DISARM))
    began = time.monotonic()
    with pytest.raises(CommandTimeout) as silent:
        fc.arm(timeout=10)
    waited = time.monotonic() - began
    assert 2.5 < waited < 5.0
    assert "MAV_CMD_COMPONENT_ARM_DISARM" in str(silent.value)
    assert fc.stats["command_timeouts"] == 1
    fc.set_param("SIM_CMD_MUTE", 0.0)
    fc.arm(timeout=5)
    assert fc.state.armed and fc.state.connected


def test_frames_with_a_bad_crc_or_an_unknown_id_are_counted_and_telemetry_goes_on(fc, recorder):
    fc.set_param("SIM_JUNK_RATE", 20.0)
    assert wait_for(
        lambda: fc.decoder_stats["bad_crc"] >= 5 and fc.decoder_stats["unknown"] >= 5, 5
    ), fc.decoder_stats
    fc.set_param("SIM_JUNK_RATE", 0.0)
    before = recorder.counts["ATTITUDE"]
    assert wait_for(lambda: recorder.counts["ATTITUDE"] > before + 5, 2)
    assert fc.state.connected
    fly_up(fc, 5.0)
    # The link object goes out once a second with what the codec dropped.
    assert wait_for(
        lambda: (
            recorder.last["FlightTelemetryStats"]["RxFailures"] >= 5
            and recorder.last["FlightTelemetryStats"]["RxUnknown"] >= 5
        ),
        2.5,
    ), recorder.last["FlightTelemetryStats"]


def test_listeners_get_the_mavlink_messages_and_the_platform_objects(fc, recorder):
    fly_up(fc, 8.0)
    fc.goto_ned(20.0, 0.0, -8.0)
    assert wait_for(lambda: recorder.last["ATTITUDE"]["pitch"] < -0.05, 5)
    for name in (
        "HEARTBEAT",
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "SYS_STATUS",
        "BATTERY_STATUS",
        "LOCAL_POSITION_NED",
        "HIGHRES_IMU",
    ):
        assert recorder.counts[name] > 0, name
    attitude = recorder.last["AttitudeActual"]
    assert attitude["Pitch"] < -2.0  # degrees, nose down while accelerating north
    assert set(attitude) >= {"Roll", "Pitch", "Yaw", "q1", "q2", "q3", "q4"}
    assert recorder.last["FlightStatus"] == {"Armed": "Armed", "FlightMode": "GUIDED"}
    assert recorder.last["PositionActual"]["Down"] == pytest.approx(-8.0, abs=0.3)
    battery = recorder.last["FlightBatteryState"]
    assert 14.0 < battery["Voltage"] < 17.0 and battery["ConsumedEnergy"] > 0
    assert recorder.last["BaroAltitude"]["Altitude"] == pytest.approx(HOME[2] + 8.0, abs=0.5)


def test_stream_rates_follow_set_message_interval(fc, recorder):
    fc.command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE, -1)
    time.sleep(0.2)
    stopped_at = recorder.counts["ATTITUDE"]
    time.sleep(0.5)
    assert recorder.counts["ATTITUDE"] == stopped_at
    # One per simulated second: TIME_SCALE a second on the wall clock. Measured 20 in the
    # second, quiet and with four busy processes on two cores.
    fc.command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE, 1e6)
    time.sleep(1.0)
    assert 0.5 * TIME_SCALE <= recorder.counts["ATTITUDE"] - stopped_at <= 1.5 * TIME_SCALE


def test_old_firmware_without_set_message_interval_gets_request_data_stream(tmp_path):
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--param", "SIM_MSGINT_OFF=1"],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    try:
        fc.start()
        assert fc.wait_connected(5)
        assert wait_for(lambda: fc.state.ned is not None and fc.state.roll is not None, 15)
        assert fc.stats["stream_fallbacks"] == len(DATA_STREAMS)
    finally:
        fc.stop()
        sim.stop()


def test_objrequest_answers_mavlink_names_and_platform_names(mav_sim):
    fc = MavlinkFlightController(mav_sim.link_url)  # no listener: objects are kept anyway
    fc.start()
    try:
        assert fc.wait_connected(5)
        attitude = fc.request_object("ATTITUDE")
        assert set(attitude) >= {"roll", "pitch", "yaw"}
        home = fc.request_object("HomeLocation")
        assert home["Latitude"] == round(HOME[0] * 1e7)
        assert fc.request_object("PositionActual") == {"North": 0.0, "East": 0.0, "Down": 0.0}
        with pytest.raises(Exception, match="neither a MAVLink message"):
            fc.request_object("NoSuchThing")
    finally:
        fc.stop()


def test_a_silent_vehicle_is_declared_lost_by_the_heartbeat_watchdog_and_found_again(mav_sim):
    fc = MavlinkFlightController(mav_sim.link_url, heartbeat_timeout_s=1.0)
    fc.start()
    try:
        assert fc.wait_connected(5)
        os.kill(mav_sim.pid, signal.SIGSTOP)  # the socket stays open; only silence
        try:
            assert wait_for(lambda: not fc.state.connected, 3)
            assert fc.stats["link_lost"] == 1
        finally:
            os.kill(mav_sim.pid, signal.SIGCONT)
        assert fc.wait_connected(5)
        assert fc.stats["connects"] == 2
    finally:
        fc.stop()


def test_resetfc_reboots_the_autopilot_and_the_driver_reconnects(fc):
    fc.reset()
    assert not fc.state.connected
    assert fc.wait_connected(10)
    assert wait_for(lambda: fc.state.flight_mode == "STABILIZE" and not fc.state.armed, 5)
    fly_up(fc, 4.0)  # streams were asked for again after the reboot


def test_the_driver_speaks_to_the_simulator_over_a_serial_pty(tmp_path):
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--serial"],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    try:
        assert sim.link_url.startswith("serial:/dev/")
        fc.start()
        assert fc.wait_connected(5)
        fly_up(fc, 3.0)
    finally:
        fc.stop()
        sim.stop()


def test_a_udp_link_listens_and_answers_whoever_spoke():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    fc = MavlinkFlightController(f"udp://127.0.0.1:{port}", heartbeat_timeout_s=1.0)
    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.settimeout(3)
    codec = MavlinkCodec(7, 1)
    fc.start()
    try:
        heartbeat = codec.encode(
            "heartbeat", mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0, 3
        )
        assert wait_for(lambda: fc.link.is_open, 2)
        vehicle.sendto(heartbeat, ("127.0.0.1", port))
        assert fc.wait_connected(2)
        assert fc.target_system == 7
        data, _ = vehicle.recvfrom(65535)  # the driver's own heartbeat comes back to us
        kinds = {m.get_type() for m in MavlinkCodec(1, 1).feed(data)}
        assert kinds & {"HEARTBEAT", "COMMAND_LONG"}
    finally:
        fc.stop()
        vehicle.close()


def test_the_codec_counts_bad_crc_unknown_ids_and_noise_without_raising():
    sender, receiver = MavlinkCodec(1, 1), MavlinkCodec(255, 190)
    good = sender.encode("heartbeat", 2, 3, 0, 0, 3)
    bad_crc = bytearray(good)
    bad_crc[-2] ^= 0x55
    unknown = bytearray(good)
    unknown[7:10] = b"\x77\x77\x00"
    messages = receiver.feed(bytes(bad_crc) + b"\x00noise\xff" + bytes(unknown) + good)
    assert [m.get_type() for m in messages] == ["HEARTBEAT"]
    assert receiver.stats.bad_crc == 1
    assert receiver.stats.unknown == 1
    assert receiver.stats.bad_data >= 1


def test_a_px4_autopilot_is_flown_with_its_own_modes_and_reposition(tmp_path):
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--autopilot", "px4"],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    try:
        fc.start()
        assert fc.wait_connected(5)
        assert wait_for(lambda: fc.state.home is not None, 5)
        assert fc.is_px4 and fc.state.flight_mode == "MANUAL"
        fly_up(fc, 12.0)  # NAV_TAKEOFF to home + 12 m above mean sea level
        assert wait_for(lambda: fc.state.flight_mode == "LOITER", 3)  # Takeoff ends in Hold
        fc.goto_ned(25.0, -10.0, -15.0)  # MAV_CMD_DO_REPOSITION, acknowledged
        assert wait_for(
            lambda: (
                fc.state.ned[0] == pytest.approx(25.0, abs=0.3)
                and fc.state.ned[1] == pytest.approx(-10.0, abs=0.3)
                and fc.state.alt == pytest.approx(15.0, abs=0.3)
            ),
            15,
        ), fc.state
        # PX4 enters Mission mode only with a valid mission on board.
        with pytest.raises(CommandRejected, match="TEMPORARILY_REJECTED.*no valid mission"):
            fc.set_mode("AUTO")
        fc.land()
        assert wait_for(lambda: not fc.state.armed, 15), fc.state
        assert fc.state.flight_mode == "LAND"
    finally:
        fc.stop()
        sim.stop()


def test_a_plain_pymavlink_script_connects_to_the_simulator_as_to_sitl(mav_sim):
    from pymavlink import mavutil

    host, port = mav_sim.tcp_address
    conn = mavutil.mavlink_connection(f"tcp:{host}:{port}", source_system=255)
    try:
        heartbeat = conn.wait_heartbeat(timeout=5)
        assert heartbeat is not None and conn.flightmode == "STABILIZE"
        conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        conn.arducopter_arm()
        ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
        assert conn.recv_match(
            type="HEARTBEAT",
            blocking=True,
            timeout=5,
            condition="HEARTBEAT.base_mode & 128",
        )
    finally:
        conn.close()


def test_px4_refusals_reach_the_driver_with_the_result_and_the_autopilots_words(tmp_path):
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--autopilot", "px4", "--param", "SIM_GPS_DISABLE=1"],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    try:
        fc.start()
        assert fc.wait_connected(5)
        assert wait_for(lambda: fc.state.home is not None, 5)
        assert not fc.state.gps_fix
        fc.arm(timeout=5)  # Manual needs no global position
        with pytest.raises(CommandRejected) as takeoff:
            fc.takeoff(10.0)
        assert takeoff.value.result_name == "MAV_RESULT_TEMPORARILY_REJECTED"
        assert "Takeoff denied! Please disarm and retry" in str(takeoff.value)
        with pytest.raises(CommandRejected, match="Hold mode not available: no global position"):
            fc.goto_ned(10.0, 0.0, -5.0)
        assert fc.state.ned[2] == pytest.approx(0.0, abs=0.05) and fc.state.flight_mode == "MANUAL"
    finally:
        fc.stop()
        sim.stop()

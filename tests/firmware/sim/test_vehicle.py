"""The simulated vehicle and its receiver-only arming, on simulated time (no I/O)."""

from __future__ import annotations

import math

import pytest

from firmware.sim.receiver import ReceiverArming
from firmware.sim.vehicle import Vehicle, VehicleConfig, lla_to_ned, ned_to_lla
from onboard.arming_frames import load_frames

FRAMES = load_frames()
DT = 0.02


def run(vehicle: Vehicle, seconds: float, pulses=None) -> None:
    for _ in range(round(seconds / DT)):
        vehicle.feed_receiver(pulses or FRAMES.safe_frame_us)
        vehicle.step(DT)


def armed_vehicle(**config) -> Vehicle:
    vehicle = Vehicle(config=VehicleConfig(**config), receiver=ReceiverArming(FRAMES))
    run(vehicle, FRAMES.arming_time_s + 0.1, FRAMES.arm_frame_us)
    assert vehicle.armed == "Armed"
    vehicle.set_flight_mode("PathPlanner")
    return vehicle


def test_arming_frame_held_for_the_arming_time_arms():
    receiver = ReceiverArming(FRAMES)
    states = [receiver.feed(FRAMES.arm_frame_us, t * DT) for t in range(200)]
    first_armed = states.index("Armed") * DT
    assert states[0] == "Arming"
    assert FRAMES.arming_time_s <= first_armed < FRAMES.arming_time_s + 0.05


def test_releasing_the_sticks_early_does_not_arm():
    receiver = ReceiverArming(FRAMES)
    for t in range(50):
        receiver.feed(FRAMES.arm_frame_us, t * DT)
    assert receiver.feed(FRAMES.safe_frame_us, 1.1) == "Disarmed"
    assert receiver.feed(FRAMES.arm_frame_us, 1.2) == "Arming"  # the hold starts over


def test_out_of_range_pulses_count_as_no_input():
    receiver = ReceiverArming(FRAMES)
    garbage = [3000] * len(FRAMES.arm_frame_us)
    assert receiver.feed(garbage, 0.0) == "Disarmed"
    assert receiver.feed([], 0.1) == "Disarmed"


def test_disarm_is_refused_while_airborne_and_accepted_once_landed():
    vehicle = armed_vehicle()
    vehicle.set_path_desired("Endpoint", (0, 0, -10))
    run(vehicle, 10)
    run(vehicle, 5, FRAMES.disarm_frame_us)
    assert vehicle.armed == "Armed"
    assert vehicle.receiver.refused_disarms >= 1
    vehicle.set_path_desired("Land", (0, 0, 0))
    run(vehicle, 10)
    assert vehicle.ned[2] == 0.0
    run(vehicle, FRAMES.disarming_time_s + 0.1, FRAMES.disarm_frame_us)
    assert vehicle.armed == "Disarmed"


def test_climb_and_horizontal_speed_stay_within_limits_without_overshoot():
    vehicle = armed_vehicle(max_horizontal=10.0, max_climb=2.0)
    vehicle.set_path_desired("Endpoint", (0, 0, -20))
    worst_climb = 0.0
    for _ in range(round(15 / DT)):
        vehicle.step(DT)
        worst_climb = max(worst_climb, -vehicle.velocity[2])
    assert worst_climb <= 2.0 + 1e-9
    assert vehicle.ned[2] == pytest.approx(-20.0, abs=0.01)
    vehicle.set_path_desired("Endpoint", (300, 0, -20))
    furthest, fastest = 0.0, 0.0
    for _ in range(round(45 / DT)):
        vehicle.step(DT)
        furthest = max(furthest, vehicle.ned[0])
        fastest = max(fastest, math.hypot(vehicle.velocity[0], vehicle.velocity[1]))
    assert fastest <= 10.0 + 1e-9
    assert furthest <= 300.0 + 0.01
    assert vehicle.ned[0] == pytest.approx(300.0, abs=0.01)


def test_a_disarmed_vehicle_does_not_move():
    vehicle = Vehicle(receiver=ReceiverArming(FRAMES))
    vehicle.set_flight_mode("PathPlanner")
    vehicle.set_path_desired("Endpoint", (50, 0, -10))
    run(vehicle, 10)
    assert vehicle.ned == [0.0, 0.0, 0.0]


def test_landing_flies_over_the_spot_then_descends():
    vehicle = armed_vehicle()
    vehicle.set_path_desired("Endpoint", (0, 0, -10))
    run(vehicle, 8)
    vehicle.set_path_desired("Land", (30, 0, 0))
    run(vehicle, 2)
    assert vehicle.ned[2] == pytest.approx(-10.0, abs=0.01)  # still at height on the way
    run(vehicle, 20)
    assert vehicle.ned == pytest.approx([30.0, 0.0, 0.0], abs=0.01)


def test_the_battery_runs_low_on_its_own_in_a_long_flight():
    vehicle = armed_vehicle(battery_capacity_mah=500.0, hover_drain_mah_s=1.0)
    vehicle.set_path_desired("Endpoint", (0, 0, -10))
    full_voltage = vehicle.voltage
    run(vehicle, 60)
    mid = vehicle.remaining
    run(vehicle, 400)
    assert 0.0 <= vehicle.remaining < mid < 1.0
    assert vehicle.remaining < 0.15
    assert vehicle.voltage < full_voltage
    assert vehicle.estimated_flight_time() < 100


def test_ned_and_lla_conversions_are_exact_inverses():
    home = (38.7369, -9.1427, 100.0)
    lat, lon, alt = ned_to_lla(123.4, -56.7, -30.0, home)
    assert lla_to_ned(lat, lon, alt, home) == pytest.approx((123.4, -56.7, -30.0), abs=1e-6)


def test_moving_home_keeps_the_vehicle_where_it_is_on_the_globe():
    vehicle = Vehicle(receiver=ReceiverArming(FRAMES))
    before = vehicle.lla()
    lat, lon, alt = ned_to_lla(100.0, 0.0, 0.0, vehicle.home)
    vehicle.set_home(lat, lon, alt)
    assert vehicle.ned[0] == pytest.approx(-100.0, abs=1e-6)
    assert vehicle.lla() == pytest.approx(before, abs=1e-9)


def test_the_path_planner_flies_waypoints_in_order_until_the_first_invalid():
    vehicle = armed_vehicle()
    vehicle.set_waypoint(0, "Endpoint", (0, 0, -10))
    vehicle.set_waypoint(1, "Endpoint", (40, 0, -10))
    vehicle.set_waypoint(2, "Endpoint", (40, 30, -15))
    vehicle.set_waypoint(3, "Invalid", (0, 0, 0))
    vehicle.set_waypoint(4, "Endpoint", (500, 500, -50))  # after Invalid: never flown
    visited = set()
    for _ in range(round(60 / DT)):
        vehicle.step(DT)
        if vehicle.plan_index is not None:
            visited.add(vehicle.plan_index)
    assert visited == {0, 1, 2, 3}
    assert vehicle.ned == pytest.approx([40.0, 30.0, -15.0], abs=0.01)

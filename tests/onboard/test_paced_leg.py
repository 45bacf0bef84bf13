"""A paced leg's target waits for a drone whose climb lags it: never more than the leash
above the drone, and the time waited is not made up by a jump. Flown with the software
flight controller's own vehicle at its maximum climb, with the agent stalling."""

from __future__ import annotations

import pytest

from firmware.sim.receiver import ReceiverArming
from firmware.sim.vehicle import Vehicle, VehicleConfig
from onboard.arming_frames import load_frames
from onboard.mission import CLIMB_LEASH_M, PacedLeg

# 300 m north climbing 200 m (a 34° slope), paced so that it climbs at 2 m/s, the
# simulated vehicle's maximum climb.
START, END = (0.0, 0.0, -50.0), (300.0, 0.0, -250.0)
CLIMB_M_S = 2.0
SPEED = CLIMB_M_S * ((300.0**2 + 200.0**2) ** 0.5) / 200.0


def test_the_target_waits_for_a_drone_below_it():
    leg = PacedLeg(START, END, SPEED)
    held = leg.advance(10.0, here=START)
    assert held[2] == pytest.approx(START[2] - CLIMB_LEASH_M)
    assert leg.advance(10.0, here=START) == pytest.approx(held)
    # Once the drone has climbed to it, the target goes on at the leg's pace from there.
    on = leg.advance(1.0, here=held)
    assert held[2] - on[2] == pytest.approx(CLIMB_M_S)
    assert not leg.done


def test_a_level_leg_waits_for_a_drone_still_climbing_to_it():
    leg = PacedLeg((0.0, 0.0, -50.0), (100.0, 0.0, -50.0), 5.0)
    assert leg.advance(4.0, here=(0.0, 0.0, -30.0)) == pytest.approx((0.0, 0.0, -50.0))
    assert leg.advance(1.0, here=(0.0, 0.0, -49.0)) == pytest.approx((5.0, 0.0, -50.0))


def test_without_the_drone_the_leg_is_paced_by_time_alone():
    leg = PacedLeg(START, END, SPEED)
    assert leg.advance(10.0)[2] == pytest.approx(START[2] - 10.0 * CLIMB_M_S)
    assert leg.advance(1000.0) == END and leg.done


def _armed() -> Vehicle:
    frames = load_frames()
    vehicle = Vehicle(config=VehicleConfig(max_climb=CLIMB_M_S), receiver=ReceiverArming(frames))
    for _ in range(round((frames.arming_time_s + 0.1) / 0.02)):
        vehicle.feed_receiver(frames.arm_frame_us)
        vehicle.step(0.02)
    vehicle.set_flight_mode("PathPlanner")
    vehicle.set_path_desired("Endpoint", START)
    while vehicle.ned[2] > START[2] + 0.1:
        vehicle.step(0.05)
    return vehicle


def _deepest_below_the_leg(leashed: bool) -> float:
    """Fly the leg with the agent stalled for 5 s of every 10 (its next target then a jump
    ahead, as a loaded agent's is); the most the vehicle was below the leg's line at its
    north."""
    vehicle, leg, t, dt, deepest = _armed(), PacedLeg(START, END, SPEED), 0.0, 0.05, 0.0
    last = 0.0
    while not (leg.done and abs(vehicle.ned[2] - END[2]) < 0.5) and t < 600.0:
        if t % 10.0 >= 5.0 and t - last >= 0.2:
            here = tuple(vehicle.ned) if leashed else None
            vehicle.set_path_desired("Endpoint", leg.advance(t - last, here))
            last = t
        vehicle.step(dt)
        t += dt
        north = min(max(vehicle.ned[0], 0.0), END[0])
        line = START[2] + (END[2] - START[2]) * north / END[0]
        deepest = max(deepest, vehicle.ned[2] - line)
    return deepest


def test_a_stalled_agent_leaves_the_vehicle_under_its_climb_only_when_not_leashed():
    leashed = _deepest_below_the_leg(leashed=True)
    assert leashed <= CLIMB_LEASH_M, leashed
    # The same stalls without the leash: each jump ahead is caught up horizontally at
    # once and vertically never, at the vehicle's maximum climb (8.8 m below here).
    unleashed = _deepest_below_the_leg(leashed=False)
    assert unleashed > 2 * CLIMB_LEASH_M, unleashed

"""The simulated vehicle's heading: along its flight, or toward a region of interest."""

from __future__ import annotations

import pytest

from .test_vehicle import armed_vehicle, run


def test_the_nose_follows_the_flight_without_a_region_of_interest():
    vehicle = armed_vehicle()
    vehicle.set_path_desired("Endpoint", (0.0, 40.0, -10.0))
    run(vehicle, 6.0)
    assert vehicle.yaw == pytest.approx(90.0, abs=1.0)


def test_the_nose_turns_toward_the_region_of_interest_at_the_yaw_rate_limit():
    vehicle = armed_vehicle(max_yaw_rate=60.0)
    vehicle.roi = (0.0, -50.0)  # due west of home
    vehicle.set_path_desired("Endpoint", (0.0, 0.0, -10.0))
    run(vehicle, 1.0)
    assert vehicle.yaw == pytest.approx(360.0 - 60.0, abs=2.0)  # a second at 60°/s
    run(vehicle, 3.0)
    assert vehicle.yaw == pytest.approx(270.0, abs=0.5)
    # Flying north, it keeps facing the point: the bearing changes, the nose follows it.
    vehicle.set_path_desired("Endpoint", (50.0, 0.0, -10.0))
    run(vehicle, 15.0)
    assert vehicle.ned[0] == pytest.approx(50.0, abs=0.5)
    assert vehicle.yaw == pytest.approx(225.0, abs=1.0)
    vehicle.roi = None
    vehicle.set_path_desired("Endpoint", (50.0, 30.0, -10.0))
    run(vehicle, 2.0)
    assert vehicle.yaw == pytest.approx(90.0, abs=1.0)


def test_a_rebooted_vehicle_forgets_its_region_of_interest():
    vehicle = armed_vehicle()
    vehicle.roi = (10.0, 10.0)
    vehicle.reboot()
    assert vehicle.roi is None

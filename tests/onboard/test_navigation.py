"""LLA↔NED with the dRonin GCS formula, and commands → navigation targets."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from onboard.fc.base import VehicleState
from onboard.navigation import (
    EARTH_RADIUS,
    NavigationProcessor,
    inside_cylinder,
    lla_to_ned,
    ned_to_lla,
)

from .fakes import HOME, FakeFlightController


def test_lla_to_ned_follows_the_dronin_formula() -> None:
    # [Paula 2018], figure 4.13, written out with its own constant.
    deg = 0.017453293
    lat, lon, alt = 40.6312, -8.6561, 42.0
    home_lat, home_lon, home_alt = HOME
    expected_n = (home_alt + 6378137) * (lat - home_lat) * deg
    expected_e = math.cos(home_lat * deg) * (home_alt + 6378137) * (lon - home_lon) * deg
    north, east, down = lla_to_ned(lat, lon, alt, HOME)
    assert north == pytest.approx(expected_n, abs=1e-3)
    assert east == pytest.approx(expected_e, abs=1e-3)
    assert down == pytest.approx(home_alt - alt)
    assert EARTH_RADIUS == 6_378_137.0


def test_one_thousandth_of_a_degree_north_is_about_111_metres() -> None:
    north, east, _ = lla_to_ned(HOME[0] + 0.001, HOME[1], HOME[2], HOME)
    assert north == pytest.approx(111.32, abs=0.05)
    assert east == pytest.approx(0.0)


@given(
    st.floats(-80, 80),
    st.floats(-179, 179),
    st.floats(-100, 3000),
    st.floats(-5000, 5000),
    st.floats(-5000, 5000),
    st.floats(-500, 100),
)
def test_ned_to_lla_is_the_exact_inverse(hlat, hlon, halt, north, east, down) -> None:
    home = (hlat, hlon, halt)
    lat, lon, alt = ned_to_lla(north, east, down, home)
    back = lla_to_ned(lat, lon, alt, home)
    assert back == pytest.approx((north, east, down), abs=1e-6)


def test_cylinder_check_uses_strict_tolerances() -> None:
    goal = (100.0, 0.0, -10.0)
    assert inside_cylinder((99.0, 1.0, -9.0), goal, horizontal_tolerance=2, vertical_tolerance=2)
    assert not inside_cylinder(
        (98.0, 0.0, -10.0), goal, horizontal_tolerance=2, vertical_tolerance=2
    )
    assert not inside_cylinder(
        (100.0, 0.0, -12.5), goal, horizontal_tolerance=2, vertical_tolerance=2
    )
    assert inside_cylinder((100.0, 0.0, -12.5), goal, horizontal_tolerance=2, vertical_tolerance=3)


def test_relative_commands_add_to_the_last_requested_target() -> None:
    fc = FakeFlightController()
    fc.move_to(3.0, 4.0, 0.0)
    nav = NavigationProcessor(fc)
    assert nav.execute("takeoff", {"altitude": 10.0}).ned == (3.0, 4.0, -10.0)
    # The drone has not climbed yet; changeN still builds on the takeoff target.
    assert nav.execute("changeN", {"value": 100.0}).ned == (103.0, 4.0, -10.0)
    assert nav.execute("changeE", {"value": -4.0}).ned == (103.0, 0.0, -10.0)
    assert nav.execute("altitude", {"value": 5.0}).ned == (103.0, 0.0, -15.0)
    fc.move_to(50.0, 1.0, -15.0)
    assert nav.execute("land", {}).ned == (50.0, 1.0, 0.0)
    assert fc.calls[:4] == [
        ("takeoff", 10.0),
        ("goto", 103.0, 4.0, -10.0),
        ("goto", 103.0, 0.0, -10.0),
        ("goto", 103.0, 0.0, -15.0),
    ]
    assert fc.calls[4] == ("land",)


def test_navigate_converts_the_coordinate_and_keeps_the_altitude() -> None:
    fc = FakeFlightController()
    nav = NavigationProcessor(fc)
    nav.execute("takeoff", {"altitude": 20.0})
    lat, lon, _ = ned_to_lla(200.0, -50.0, 0.0, HOME)
    target = nav.execute("navigate", {"lat": lat, "lon": lon, "altitude_delta": 5.0})
    assert target.ned == pytest.approx((200.0, -50.0, -25.0))


def test_navigation_without_a_position_is_refused() -> None:
    nav = NavigationProcessor(FakeFlightController())
    with pytest.raises(Exception, match="position"):
        nav.plan("changeN", {"value": 1.0}, VehicleState())

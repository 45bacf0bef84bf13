"""A drone's state at a glance, its ground track and battery time left: plain functions."""

from __future__ import annotations

import math

import pytest

from fleet import state
from fleet.state import Motion, battery_time_left, drain_rate, drone_state, ground_track


def _state(**fields: object) -> str:
    base = {"online": True, "armed": False, "airborne": False}
    return drone_state(**{**base, **fields})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("fields", "expected"),
    [
        ({}, state.ON_GROUND),
        ({"armed": True}, state.ARMED),
        ({"armed": True, "airborne": True, "flight_mode": "PositionHold"}, state.AIRBORNE),
        ({"armed": True, "airborne": True, "flight_mode": "RTL"}, state.RETURNING),
        ({"armed": True, "airborne": True, "flight_mode": "AUTO.RTL"}, state.RETURNING),
        ({"armed": True, "airborne": True, "flight_mode": "ReturnToBase"}, state.RETURNING),
        # A return mode on the ground is not a return.
        ({"armed": False, "airborne": False, "flight_mode": "RTL"}, state.ON_GROUND),
        ({"airborne": True, "battery_remaining": 0.25}, state.LOW_BATTERY),
        ({"airborne": True, "battery_remaining": 0.26}, state.AIRBORNE),
        ({"battery_remaining": 0.1, "flight_mode": "RTL", "airborne": True}, state.LOW_BATTERY),
        ({"online": False, "airborne": True, "battery_remaining": 0.1}, state.LOST_LINK),
        ({"online": False}, state.LOST_LINK),
    ],
)
def test_the_most_urgent_state_wins(fields: dict, expected: str) -> None:
    assert _state(**fields) == expected


def test_the_low_battery_threshold_can_be_set() -> None:
    assert _state(battery_remaining=0.35, low_battery=0.4) == state.LOW_BATTERY
    assert _state(battery_remaining=None) == state.ON_GROUND


def test_state_of_reads_the_api_shape_with_missing_parts() -> None:
    assert state.state_of({"drone_id": "A", "online": False}) == state.LOST_LINK
    drone = {"online": True, "armed": True, "airborne": True, "battery": None, "flight_mode": ""}
    assert state.state_of(drone) == state.AIRBORNE
    assert state.state_of({**drone, "battery": {"remaining": 0.05}}) == state.LOW_BATTERY
    assert set(state.LABELS) == set(state.STATES)


def test_ground_track_gives_speed_and_course() -> None:
    # 0.001° of latitude is 111.2 m: 10 s north is 11.12 m/s on course 0°.
    speed, course = ground_track((40.0, -8.0), (40.001, -8.0), 10.0)  # type: ignore[misc]
    assert speed == pytest.approx(11.12, abs=0.01)
    assert course == pytest.approx(0.0, abs=0.01)
    east = 111.195 * math.cos(math.radians(40.0))  # metres per 0.001° of longitude there
    speed, course = ground_track((40.0, -8.0), (40.0, -7.999), 1.0)  # type: ignore[misc]
    assert speed == pytest.approx(east, rel=1e-3) and course == pytest.approx(90.0, abs=0.01)
    _speed, course = ground_track((40.0, -8.0), (39.999, -8.001), 10.0)  # type: ignore[misc]
    # South-west: as far south as west in degrees, but a degree of longitude is shorter.
    assert course == pytest.approx(180 + math.degrees(math.atan2(east, 111.195)), abs=0.1)


def test_a_hovering_drone_has_no_course_and_no_time_means_no_track() -> None:
    speed, course = ground_track((40.0, -8.0), (40.000001, -8.0), 1.0)  # type: ignore[misc]
    assert speed < state.MIN_SPEED_FOR_HEADING and course is None
    assert ground_track((40.0, -8.0), (40.001, -8.0), 0.0) is None


def test_battery_time_left_from_the_measured_drain() -> None:
    assert drain_rate([(0.0, 0.9), (5.0, 0.89)]) is None  # too short a span
    assert drain_rate([(0.0, 0.9), (20.0, 0.88)]) == pytest.approx(0.001)
    assert drain_rate([(0.0, 0.5), (30.0, 0.6)]) is None  # charging
    assert battery_time_left(0.5, 0.001) == pytest.approx(500.0)
    assert battery_time_left(0.5, None) is None and battery_time_left(None, 0.1) is None
    assert battery_time_left(0.5, 0.0) is None


def test_motion_follows_a_drone_between_updates() -> None:
    motion = Motion()
    first = motion.update("A", 100.0, {"lat": 40.0, "lon": -8.0, "alt": 10}, 0.9)
    assert first == {
        "ground_speed": None,
        "heading": None,
        "battery_time_left_s": None,
        "battery_drain_per_s": None,
    }
    second = motion.update("A", 110.0, {"lat": 40.001, "lon": -8.0, "alt": 10}, 0.89)
    assert second["ground_speed"] == pytest.approx(11.12, abs=0.01)
    assert second["heading"] == pytest.approx(0.0, abs=0.1)
    # 0.01 in 10 s: 0.001/s, 0.89 left is 890 s.
    assert second["battery_time_left_s"] == pytest.approx(890.0, abs=0.5)
    assert second["battery_drain_per_s"] == pytest.approx(0.001)
    # Another drone has its own track; no position, nothing to say.
    assert motion.update("B", 110.0, None, 0.5)["ground_speed"] is None


def test_a_fresh_battery_starts_a_new_drain_measurement() -> None:
    motion = Motion()
    here = {"lat": 40.0, "lon": -8.0, "alt": 0}
    motion.update("A", 0.0, here, 0.40)
    assert motion.update("A", 20.0, here, 0.38)["battery_drain_per_s"] == pytest.approx(0.001)
    # Swapped for a full battery: the old readings no longer say anything.
    assert motion.update("A", 30.0, here, 0.99)["battery_drain_per_s"] is None
    drain = motion.update("A", 45.0, here, 0.985)["battery_drain_per_s"]
    assert drain == pytest.approx(0.005 / 15, rel=1e-3)
    # A reading a little above the last one is noise, not a new battery.
    assert motion.update("A", 50.0, here, 0.99)["battery_drain_per_s"] == 0.0
    drain = motion.update("A", 60.0, here, 0.98)["battery_drain_per_s"]
    assert drain == pytest.approx(0.01 / 30, rel=1e-3)

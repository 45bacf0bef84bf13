from __future__ import annotations

import pytest

from missions.selection import Candidate, is_available, select_drones
from tests.missions.planning import point_at

TARGET = point_at(0, 0)


def drone(drone_id, *, metres=0.0, battery=0.9, online=True, in_mission=False, position=True):
    return Candidate(
        drone_id=drone_id,
        online=online,
        in_mission=in_mission,
        battery=battery,
        position=point_at(metres, 0) if position else None,
    )


def test_nearest_available_drone_comes_first():
    chosen = select_drones(
        [drone("FAR", metres=300), drone("NEAR", metres=40), drone("MID", metres=120)],
        target=TARGET,
        count=2,
        reserve=0.3,
    )
    assert [c.drone_id for c in chosen] == ["NEAR", "MID"]


def test_equally_distant_drones_are_ordered_by_battery_higher_first():
    chosen = select_drones(
        [drone("LOW", metres=50, battery=0.5), drone("HIGH", metres=50.2, battery=0.95)],
        target=TARGET,
        count=2,
        reserve=0.3,
    )
    assert [c.drone_id for c in chosen] == ["HIGH", "LOW"]


@pytest.mark.parametrize(
    "unavailable",
    [
        drone("OFFLINE", online=False),
        drone("BUSY", in_mission=True),
        drone("TIRED", battery=0.25),
        drone("AT_RESERVE", battery=0.3),
        drone("UNKNOWN_BATTERY", battery=None),
        drone("NO_FIX", position=False),
    ],
)
def test_offline_busy_low_or_unlocated_drones_are_never_chosen(unavailable):
    assert not is_available(unavailable, reserve=0.3)
    chosen = select_drones([unavailable, drone("OK", metres=500)], target=TARGET, count=2)
    assert [c.drone_id for c in chosen] == ["OK"]


def test_excluded_drone_is_not_chosen_to_replace_itself():
    chosen = select_drones(
        [drone("FAILING", metres=1), drone("OTHER", metres=90)],
        target=TARGET,
        count=1,
        exclude=["FAILING"],
    )
    assert [c.drone_id for c in chosen] == ["OTHER"]


def test_fewer_drones_come_back_when_fewer_are_available():
    assert select_drones([drone("ONLY")], target=TARGET, count=3) == [drone("ONLY")]
    assert select_drones([], target=TARGET, count=2) == []

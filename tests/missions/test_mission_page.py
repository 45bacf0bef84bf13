"""A mission's progress per drone: steps done, time still needed and the battery left at
the end, from the remaining route, the measured speed and the measured drain."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from missions.estimates import (
    DEFAULT_SPEED_M_S,
    estimate,
    measured_speed,
    mission_routes,
    route_length,
)
from missions.geo import LocalFrame
from missions.models import Assignment, Mission, Step, StepStatus

ORIGIN = (40.0, -8.0)
FRAME = LocalFrame(*ORIGIN)


def north(metres: float) -> list[float]:
    return list(FRAME.point_to_latlon((metres, 0.0)))


def test_the_estimate_is_distance_over_speed_and_drain_over_that_time() -> None:
    # 600 m at 5 m/s: 120 s; 0.001/s for 120 s takes 0.12 off 0.62 → 0.50, 0.20 over 0.30.
    got = estimate(600.0, 5.0, 0.62, 0.001, reserve=0.3)
    assert got["time_remaining_s"] == pytest.approx(120.0)
    assert got["battery_at_end"] == pytest.approx(0.50)
    assert got["battery_margin"] == pytest.approx(0.20)
    # Not enough: a negative margin, shown as such.
    assert estimate(3000.0, 5.0, 0.62, 0.001, reserve=0.3)["battery_margin"] == pytest.approx(-0.28)


def test_the_estimate_says_what_it_does_not_know() -> None:
    no_drain = estimate(100.0, 4.0, 0.8, None)
    assert no_drain["time_remaining_s"] == pytest.approx(25.0)
    assert no_drain["battery_at_end"] is None and no_drain["battery_margin"] is None
    unknown_speed = estimate(100.0, None, None, 0.001)
    assert unknown_speed["time_remaining_s"] == pytest.approx(100.0 / DEFAULT_SPEED_M_S)
    assert unknown_speed["battery_at_end"] is None
    assert estimate(0.0, 5.0, 0.5, 0.01)["battery_at_end"] == pytest.approx(0.5)


def test_route_length_runs_through_the_waypoints_in_order() -> None:
    assert route_length(north(0), [north(100), north(300)]) == pytest.approx(300.0, rel=1e-3)
    # Out and back counts both ways.
    assert route_length(north(0), [north(100), north(0)]) == pytest.approx(200.0, rel=1e-3)
    assert route_length(None, [north(100)]) == 0.0
    assert route_length(None, [north(100), north(150)]) == pytest.approx(50.0, rel=1e-3)


def test_measured_speed_ignores_legs_too_short_to_tell() -> None:
    legs = [(north(0), 0.0), (north(100), 20.0), (north(101), 30.0), (north(201), 40.0)]
    # 200 m in 30 s over the two real legs; the 1 m leg is hovering, not flying.
    assert measured_speed(legs) == pytest.approx(200.0 / 30.0, rel=1e-3)
    assert measured_speed([(north(0), 0.0)]) is None
    assert measured_speed([]) is None


@pytest.mark.django_db
def test_routes_follow_the_steps_each_drone_has_done(world) -> None:
    mission = Mission.objects.create(organisation=world.org, name="line", status="running")
    started = datetime(2026, 1, 1, 12, 0, tzinfo=UTC)
    for index in range(4):
        done = index < 2
        Step.objects.create(
            mission=mission,
            index=index,
            command="navigate",
            params={"lat": north(index * 100)[0], "lon": north(index * 100)[1]},
            status=StepStatus.COMPLETED if done else StepStatus.PENDING,
            drone=world.drone if done else None,
            position={"lat": north(index * 100)[0], "lon": north(index * 100)[1], "alt": 10}
            if done
            else None,
            ended_at=started + timedelta(seconds=20 * index) if done else None,
        )
    Assignment.objects.create(mission=mission, drone=world.drone, step_indexes=[0, 1, 2, 3])
    route = mission_routes(mission.pk)["ACME_1"]
    assert (route.done, route.total, route.current) == (2, 4, 2)
    assert route.speed_m_s == pytest.approx(5.0, rel=1e-3)  # 100 m in 20 s
    lat, lon = north(100)
    got = route.progress({"lat": lat, "lon": lon, "alt": 10}, 0.8, 0.001, 0.3)
    assert got["remaining_m"] == pytest.approx(200.0, rel=1e-3)
    assert got["time_remaining_s"] == pytest.approx(40.0, rel=1e-3)
    assert got["battery_at_end"] == pytest.approx(0.76, abs=1e-3)
    assert got["steps_done"] == 2 and got["steps_total"] == 4 and got["current_step"] == 2

"""A scene several airspace tests start from: a drone that failed mid-mission and the
drone waiting to replace it."""

from __future__ import annotations

from typing import Any

from fleet.models import Drone
from missions.creation import create_mission
from missions.planning import mission_steps
from missions.startstop import start_mission
from tests.missions.conftest import online_drone, point_at
from tests.missions.test_services import _alarm_event, _complete


def failing_over_origin(world: Any, home_north: float, *, with_home: bool = False) -> tuple:
    """ACME_A (home `home_north` m north of the origin, recorded when `with_home`) flew a
    mission north and stopped failing over the origin, 10 m up; ACME_B waits on the
    ground 150 m south. (failing drone, mission, its assignment, the alarm event)."""
    failing = online_drone(world.org, "ACME_A", north=home_north)
    online_drone(world.org, "ACME_B", north=-150)
    points = [point_at(100.0 * i, 0.0) for i in range(4)]
    mission = create_mission(
        organisation=world.org, name="north", steps=mission_steps(points, altitude=10)
    )
    assignment = start_mission(mission, drone=failing).assignment
    _complete(failing, mission, assignment, [0, 1, 2, 3])
    here = point_at(0, 0)
    home = {"home": list(point_at(home_north, 0))} if with_home else {}
    Drone.objects.filter(pk=failing.pk).update(
        airborne=True, alt=10.0, lat=here[0], lon=here[1], **home
    )
    failing.refresh_from_db()
    return failing, mission, assignment, _alarm_event(mission, failing, north=0)


def replace(mission: Any, assignment: Any, alarm: Any, **options: Any) -> Any:
    """The failing drone's replacement, as the replacement task decides it."""
    from missions import replacement

    return replacement.replace_drone(
        mission_id=str(mission.pk),
        assignment_id=str(assignment.pk),
        alarm_event_id=alarm.pk,
        **options,
    )

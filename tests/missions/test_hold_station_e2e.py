"""A panic call's drone holding station down to the battery reserve, end to end: simulated
drones (the real onboard agent over UAVTalk), the real gateway and Celery worker.

Rule: the call stays on station until released; a drone whose battery reaches the reserve
on station is relieved: another drone takes the station, and this one returns home,
lands and disarms rather than coming down by the caller.
"""

from __future__ import annotations

import pytest

from missions import panic
from missions.models import Assignment, Mission, MissionStatus
from runtime.processes import wait_for
from tests.support.experiments import api, ground  # noqa: F401 - `ground` is a shared fixture

from .conftest import point_at
from .sky import metres
from .test_experiments import drone_row, sky  # noqa: F401 - `sky` is a fixture

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
# Hovering draws 15 A: with a reserve of 50 %, 2 000 mAh reach it after about 4 flight
# minutes (12 s here), well before the agent's own CRITICAL (25 %, 2 minutes later), so a
# busy machine cannot blur which of the two brought the drone down.
SMALL_BATTERY_MAH = 2000
RESERVE = 0.5


def test_a_panic_drone_at_the_battery_reserve_is_relieved_and_returns_home_to_land(
    world_tx,
    sky,  # noqa: F811
    settings,
):
    settings.MISSIONS_BATTERY_RESERVE = RESERVE  # the ground's setting (docs/failsafe.md)
    sky.add_drone("ACME_PS1", north=60, battery_capacity_mah=SMALL_BATTERY_MAH)
    sky.add_drone("ACME_PS2", north=-150)
    sky.wait_online()
    caller = point_at(0, 0)
    response = api(world_tx.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert response.status_code == 201, response.json()
    mission_id = response.json()["id"]
    assert Mission.objects.get(pk=mission_id).assignments.get().drone.drone_id == "ACME_PS1"

    def over_caller(drone_id: str) -> bool:
        drone = drone_row(drone_id)
        return drone.airborne and metres((drone.lat, drone.lon), caller) < 2.0

    assert wait_for(lambda: over_caller("ACME_PS1"), 60), sky.describe()
    # What Celery beat runs every MISSIONS_RESUME_INTERVAL_S, here as often as we look.
    relieved = wait_for(panic.relieve_stations, 90, interval=0.1)
    assert relieved == ["ACME_PS1"], sky.describe()
    battery = drone_row("ACME_PS1").battery_remaining
    assert 0.25 < battery <= RESERVE, battery

    mission = Mission.objects.get(pk=mission_id)
    relief = mission.assignments.get(reason=Assignment.Reason.REPLACEMENT)
    assert relief.drone.drone_id == "ACME_PS2"
    assert mission.status == MissionStatus.RUNNING  # the call goes on

    def home_disarmed(drone_id: str, north: float) -> bool:
        drone = drone_row(drone_id)
        return not drone.armed and metres((drone.lat, drone.lon), point_at(north, 0)) < 2.5

    assert wait_for(lambda: home_disarmed("ACME_PS1", 60), 60), sky.describe()
    assert wait_for(lambda: over_caller("ACME_PS2"), 60), sky.describe()
    assert Mission.objects.get(pk=mission_id).status == MissionStatus.RUNNING
    assert panic.relieve_stations() == []  # once

    released = api(world_tx.operator).post(f"/api/v1/missions/{mission_id}/release/")
    assert released.json()["status"] == "completed", released.json()
    assert wait_for(lambda: home_disarmed("ACME_PS2", -150), 60), sky.describe()

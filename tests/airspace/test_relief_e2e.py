"""A replacement flying to a drone that is still on its way home, flown: a panic call's
drone relieved at the battery reserve returns home along the very line its relief flies
in on (its home lies between the relief's home and the station), with simulated drones
(the real onboard agent), the real gateway and Celery worker. Both reach their ends and
their reported positions never come within the separation minima (30 m horizontally
while closer than 10 m vertically, docs/airspace.md)."""

from __future__ import annotations

import pytest

from missions import panic
from missions.models import Assignment, Mission
from runtime.processes import wait_for
from tests.missions.conftest import point_at
from tests.missions.sky import metres
from tests.missions.test_experiments import drone_row, sky  # noqa: F401 - `sky` is a fixture
from tests.support.experiments import api, ground  # noqa: F401 - a shared fixture

from .test_e2e import Track

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
# 2 000 mAh at a 15 A hover reach a 90 % reserve after about 50 flight seconds, long
# before the agent's own CRITICAL at 25 %. At 5× time (rather than the usual 20×) the
# relieved drone's way home lasts seconds of the test's time, so the relief takes off and
# flies in while it is still on it.
SMALL_BATTERY_MAH, RESERVE, TIME_SCALE = 2000, 0.9, 5.0
STATION, RELIEVED_HOME, RELIEF_HOME = (0.0, 0.0), -100.0, -200.0


def _landed_at(drone_id: str, north: float) -> bool:
    drone = drone_row(drone_id)
    return not drone.armed and metres((drone.lat, drone.lon), point_at(north, 0)) < 2.5


def _over(drone_id: str, place: tuple[float, float]) -> bool:
    drone = drone_row(drone_id)
    return drone.airborne and metres((drone.lat, drone.lon), place) < 2.0


def test_a_relief_flying_in_along_the_relieved_drones_way_home_keeps_separated(
    world_tx,
    sky,  # noqa: F811
    settings,
):
    settings.MISSIONS_BATTERY_RESERVE = RESERVE
    sky.time_scale = TIME_SCALE
    sky.add_drone("ACME_RV1", north=RELIEVED_HOME, battery_capacity_mah=SMALL_BATTERY_MAH)
    sky.add_drone("ACME_RV2", north=RELIEF_HOME, fc="mavlink")
    sky.wait_online()
    caller = point_at(*STATION)
    response = api(world_tx.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert response.status_code == 201, response.json()
    mission_id = response.json()["id"]
    assert wait_for(lambda: _over("ACME_RV1", caller), 60), sky.describe()

    track = Track(["ACME_RV1", "ACME_RV2"])
    track.start()
    try:
        # What Celery beat runs every MISSIONS_RESUME_INTERVAL_S, here as often as we look.
        assert wait_for(panic.relieve_stations, 90, interval=0.1) == ["ACME_RV1"]
        relief = Mission.objects.get(pk=mission_id).assignments.get(
            reason=Assignment.Reason.REPLACEMENT
        )
        assert relief.drone.drone_id == "ACME_RV2"
        assert wait_for(lambda: _landed_at("ACME_RV1", RELIEVED_HOME), 90), sky.describe()
        assert wait_for(lambda: _over("ACME_RV2", caller), 90), sky.describe()
    finally:
        track.done.set()
        track.join(5)
    both = [s for s in track.samples if len(s) == 2]
    assert both, "the two drones were never seen in the air together"
    for sample in both:
        a, b = sample.values()
        apart_h, apart_v = metres(a[:2], b[:2]), abs(a[2] - b[2])
        assert apart_h >= 30.0 or apart_v >= 10.0, (apart_h, apart_v, sample)
    released = api(world_tx.operator).post(f"/api/v1/missions/{mission_id}/release/")
    assert released.json()["status"] == "completed", released.json()

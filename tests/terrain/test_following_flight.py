"""A terrain-following survey over the 200 m hill flown by a simulated drone (the software
flight controller and the real onboard agent): along its recorded track the drone stays
at its height above the DEM's ground, within the tolerance and the flight controller's
own tracking error."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from fleet import envelopes
from missions.models import MissionStatus, Step, StepStatus
from terrain.importer import import_path
from tests.missions.sky import Sky, metres
from tests.support.experiments import api, ground, wait_status  # noqa: F401

from .dem import HOME, hill_tile, write_hgt
from .test_following import HEIGHT, TOLERANCE, coverage

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
# What a multicopter's position controller may lag its target by, on top of the
# tolerance (the simulator's own tracking of a moving target).
TRACKING_M = 5.0
# Samples this close, horizontally, to where the drone took off or to the last waypoint
# may be the take-off's climb or the landing's descent.
END_RADIUS_M = 5.0


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = Sky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


class Track(threading.Thread):
    """The drone's reported position (lat, lon, height above home) while airborne, with
    the index of the mission's latest step begun when it was read."""

    def __init__(self, drone_id: str, mission_id: int) -> None:
        super().__init__(daemon=True)
        self.drone_id, self.mission_id = drone_id, mission_id
        self.samples: list[tuple[float, float, float, int]] = []
        self.done = threading.Event()

    def run(self) -> None:
        from django.db import connection

        from fleet.models import Drone

        begun = Step.objects.filter(mission_id=self.mission_id).exclude(status=StepStatus.PENDING)
        try:
            while not self.done.is_set():
                step = begun.order_by("-index").values_list("index", flat=True).first()
                d = Drone.objects.get(drone_id=self.drone_id)
                if d.airborne and d.lat is not None and d.alt is not None and step is not None:
                    self.samples.append((d.lat, d.lon, d.alt, step))
                time.sleep(0.05)
        finally:
            connection.close()


def flown_legs(mission_id: int, samples: list) -> list[tuple[float, float, float]]:
    """The samples read from the start of the first leg to the arrival at the last
    waypoint, except those over where the drone took off or over the last waypoint: the
    take-off's climb, and the photo and landing at the last waypoint, are not flown at the
    height above the ground. Those two are told by where the drone is, not only by which
    step the ground had recorded as begun: the drone's progress and its position reach
    the ground by different ways, and on a loaded machine either may come later."""
    steps = Step.objects.filter(mission_id=mission_id)
    first = min(s.index for s in steps if s.command == "navigate")
    arrived = max(s.index for s in steps if s.command == "wait_for_flight")
    last = max((s for s in steps if s.command == "navigate"), key=lambda s: s.index)
    ends = [samples[0][:2], (last.params["lat"], last.params["lon"])] if samples else []
    return [
        (lat, lon, alt)
        for lat, lon, alt, step in samples
        if first <= step <= arrived and all(metres((lat, lon), e) > END_RADIUS_M for e in ends)
    ]


def test_the_survey_is_flown_at_its_height_above_the_ground(world_tx, sky, terrain_dir, tmp_path):
    dem = hill_tile()
    import_path(write_hgt(tmp_path, dem))
    envelopes.set_envelope(
        world_tx.org, {"max_height": 400, "max_distance": 2000, "home": list(HOME)}
    )
    sky.add_drone("ACME_T1")
    sky.wait_online()
    client = api(world_tx.operator)
    created = client.post("/api/v1/missions/", coverage(), format="json")
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    track = Track("ACME_T1", mission_id)
    track.start()
    started = client.post(f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_T1", "confirm_beyond_defaults": True}, format="json")  # fmt: skip
    assert started.status_code == 200, started.json()
    try:
        finished = wait_status(mission_id, {"completed", "failed", "stopped"}, 180)
        assert finished.status == MissionStatus.COMPLETED, sky.describe()
    finally:
        track.done.set()
        track.join(5)
    home_ground = dem.bilinear(*HOME)
    flown = flown_legs(mission_id, track.samples)
    assert len(flown) > 50, "the drone was hardly seen flying its legs"
    agl = np.array([alt + home_ground - dem.bilinear(lat, lon) for lat, lon, alt in flown])
    over_hill = [alt for lat, lon, alt in flown if dem.bilinear(lat, lon) > 100]
    assert over_hill and max(over_hill) > 200, "the drone never climbed over the hill"
    # Along its legs, never lower above the ground than the height less the tolerance and
    # tracking, nor higher than the height plus them: the paced target waits for a drone
    # whose climb lags it (onboard/mission.py), so a loaded machine slows the legs down
    # instead of leaving the drone under a rising slope.
    assert agl.min() >= HEIGHT - TOLERANCE - TRACKING_M, agl.min()
    assert agl.max() <= HEIGHT + TOLERANCE + TRACKING_M, agl.max()

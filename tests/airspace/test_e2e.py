"""Two simulated drones (the software flight controller and the real onboard agent) fly
missions whose legs cross: at the same height the second is refused; 20 m apart both are
accepted, flown, and their reported positions never come within the separation minima
(30 m horizontally while closer than 10 m vertically)."""

from __future__ import annotations

import itertools
import threading
import time

import pytest

from airspace.models import Reservation
from missions.models import MissionStatus
from tests.missions.conftest import point_at
from tests.missions.sky import Sky, metres
from tests.support.experiments import api, ground, wait_status  # noqa: F401
from tests.support.ground import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = Sky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


def crossing(start: tuple[float, float], end: tuple[float, float], altitude: float) -> dict:
    a, b = point_at(*start), point_at(*end)
    return {
        "name": f"across at {altitude:g} m",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": b[0], "lon": b[1]}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": a[0], "lon": a[1]}},
            {"command": "wait_for_flight"},
            {"command": "land"},
        ],
    }


class Track(threading.Thread):
    """Samples every drone's reported position from the database until stopped."""

    def __init__(self, drone_ids: list[str]) -> None:
        super().__init__(daemon=True)
        self.drone_ids, self.samples, self.done = drone_ids, [], threading.Event()

    def run(self) -> None:
        from django.db import connection

        from fleet.models import Drone

        try:
            while not self.done.is_set():
                rows = Drone.objects.filter(drone_id__in=self.drone_ids, airborne=True)
                self.samples.append({d.drone_id: (d.lat, d.lon, d.alt) for d in rows})
                time.sleep(0.02)
        finally:
            connection.close()


def start(world, mission: dict, drone_id: str):  # type: ignore[no-untyped-def]
    client = api(world.operator)
    created = client.post("/api/v1/missions/", mission, format="json")
    assert created.status_code == 201, created.json()
    mission_id = created.json()["id"]
    started = client.post(
        f"/api/v1/missions/{mission_id}/start/", {"drone": drone_id}, format="json"
    )
    return mission_id, started


def test_crossing_missions_twenty_metres_apart_fly_separated(world_tx, sky):
    sky.add_drone("ACME_X1", north=-80)
    sky.add_drone("ACME_X2", east=-80)
    sky.wait_online()
    first_id, first = start(world_tx, crossing((-80, 0), (80, 0), 20), "ACME_X1")
    assert first.status_code == 200, first.json()
    _, same_height = start(world_tx, crossing((0, -80), (0, 80), 20), "ACME_X2")
    assert same_height.status_code == 409 and same_height.json()["code"] == "conflict"
    assert "drone ACME_X1" in same_height.json()["error"]

    track = Track(["ACME_X1", "ACME_X2"])
    track.start()
    second_id, second = start(world_tx, crossing((0, -80), (0, 80), 40), "ACME_X2")
    assert second.status_code == 200, second.json()
    try:
        for mission_id in (first_id, second_id):
            assert wait_status(mission_id, {"completed", "failed", "stopped"}, 120).status == (
                MissionStatus.COMPLETED
            ), sky.describe()
    finally:
        track.done.set()
        track.join(5)
    both = [s for s in track.samples if len(s) == 2]
    assert len(both) > 20, "the two drones were never seen in the air together"
    for sample in both:
        (a, b) = sample.values()
        apart_h = metres(a[:2], b[:2])
        apart_v = abs(a[2] - b[2])
        # Separated: horizontally by the minimum, or vertically by the minimum.
        assert apart_h >= 30.0 or apart_v >= 10.0, (apart_h, apart_v, sample)
    # Both landed: their reservations end.
    assert wait_for(
        lambda: (
            api(world_tx.viewer)
            .get(f"/api/v1/organisations/{world_tx.org.slug}/reservations/")
            .json()["reservations"]
            == []
        ),
        30,
    ), list(Reservation.objects.values_list("drone__drone_id", "end_reason", "ended_at"))
    assert set(itertools.chain(Reservation.objects.values_list("end_reason", flat=True))) <= {
        "plan ended",
        "landed",
    }

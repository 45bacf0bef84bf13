"""The agents' own separation check end to end: the real ground (gateway, Celery worker,
the live-separation pass relaying traffic), simulated drones (the software flight
controller and the real onboard agent, UAVTalk and MAVLink) on a real Mosquitto.

The drones are flown by control requests put straight on the outbox, past the ground's
reservation check, as a drone off its plan would fly; the ground's own hold is switched
off (AIRSPACE_LIVE_HOLD), so whatever keeps them apart is the agents' check."""

from __future__ import annotations

import math
import threading
import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import pytest

from airspace import live
from airspace.models import Reservation
from alerts.models import Alert
from fleet.models import Drone
from onboard import protocol
from tests.airspace.test_e2e import Track
from tests.missions.conftest import point_at
from tests.missions.sky import Sky, metres
from tests.support.experiments import ground  # noqa: F401
from tests.support.ground import wait_for
from workers import outbox

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# Slow enough for a pass every half second to see the drones move between passes.
SCALE = 2.0
PASS_S = 0.5


class Passes(threading.Thread):
    """Stands in for Celery beat's airspace.watch_separation: one pass every PASS_S."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.done, self.held = threading.Event(), []

    def run(self) -> None:
        from django.db import connection

        try:
            while not self.done.wait(PASS_S):
                self.held += live.watch()
        finally:
            connection.close()

    def stop(self) -> None:
        self.done.set()
        self.join(5)


@pytest.fixture
def sky(world_tx, ground, tmp_path, settings):  # type: ignore[no-untyped-def]  # noqa: F811
    settings.AIRSPACE_LIVE_HOLD = False
    s = Sky(tmp_path, world_tx.org.slug, ground, time_scale=SCALE).start()
    passes = Passes()
    passes.start()
    s.passes = passes  # type: ignore[attr-defined]
    yield s
    passes.stop()
    s.close()


def command(drone_id: str, name: str, **params: float) -> None:
    outbox.send_to_drone(drone_id, "control", protocol.control_request(name, params).to_dict())


def take_off(drone_ids: list[str], altitude: float) -> None:
    for drone_id in drone_ids:
        command(drone_id, "arm")
    assert wait_for(lambda: Drone.objects.filter(drone_id__in=drone_ids, armed=True).count() == len(drone_ids), 20)  # fmt: skip
    for drone_id in drone_ids:
        command(drone_id, "takeoff", altitude=altitude)
    high = Drone.objects.filter(drone_id__in=drone_ids, airborne=True, alt__gte=altitude - 1)
    assert wait_for(lambda: high.count() == len(drone_ids), 40)


def test_two_drones_on_a_collision_course_hold_themselves_before_the_minima(world_tx, sky):
    sky.add_drone("ACME_T1", north=-100, fc="uavtalk")
    sky.add_drone("ACME_T2", north=100, fc="mavlink")
    sky.wait_online()
    take_off(["ACME_T1", "ACME_T2"], 20)
    track = Track(["ACME_T1", "ACME_T2"])
    track.start()
    try:
        # Head on at one height: each to where the other took off.
        command("ACME_T1", "navigate", lat=point_at(100, 0)[0], lon=point_at(100, 0)[1])
        command("ACME_T2", "navigate", lat=point_at(-100, 0)[0], lon=point_at(-100, 0)[1])
        alerts = Alert.objects.filter(severity="critical", title__contains="Separation:")
        assert wait_for(lambda: alerts.count() >= 2, 40), sky.describe()
        # Each holds where it decided to: braking overshoots it and flies back; then
        # nothing moves them on.
        time.sleep(5.0)
        stopped = {d.drone_id: (d.lat, d.lon) for d in Drone.objects.filter(airborne=True)}
        time.sleep(2.0)
        still = {d.drone_id: (d.lat, d.lon) for d in Drone.objects.filter(airborne=True)}
    finally:
        track.done.set()
        track.join(5)
    assert {a.drone_id for a in alerts} == {"ACME_T1", "ACME_T2"}
    assert sky.passes.held == []  # the ground held nobody: the agents did
    both = [s for s in track.samples if len(s) == 2]
    assert len(both) > 20, "the two drones were never seen in the air together"
    closest = min(metres(a[:2], b[:2]) for a, b in (tuple(s.values()) for s in both))
    assert closest >= 30.0, closest  # same height: the horizontal minimum held
    assert closest < 180.0, closest  # they did close in before holding
    for drone_id, where in stopped.items():
        assert metres(where, still[drone_id]) < 2.0, (drone_id, where, still[drone_id])


def flight_track(folder: Path) -> list[tuple[float, float, float]]:
    """(north, east, height above home) of the drone's own flight record (the DFI archive
    its agent closes at the disarm, docs/dfi-format.md), from MAVLink LOCAL_POSITION_NED."""
    for archive in sorted(folder.glob("*.dfi")):
        if not zipfile.is_zipfile(archive):
            continue  # still being written
        with zipfile.ZipFile(archive) as zf:
            top = ElementTree.fromstring(zf.read("description.xml"))
            group = top.find(".//toplevelgroup[@name='LOCAL_POSITION_NED']")
            if group is None:
                continue
            names = [child.get("name") for child in group]
            x, y, z = (names.index(n) for n in ("x", "y", "z"))
            text = zf.read(group.get("file")).decode()
        rows = [line.split(",") for line in text.splitlines() if line]
        return [(float(r[x]), float(r[y]), -float(r[z])) for r in rows]
    return []


def test_a_drone_whose_link_is_cut_keeps_its_band_on_the_way_home(world_tx, sky):
    sky.time_scale = 5.0  # no traffic to follow here: only the band matters
    drone = sky.add_drone("ACME_L1", fc="mavlink", extra=["--link-loss-timeout", "0.5"])
    sky.wait_online()
    take_off(["ACME_L1"], 30)
    away = point_at(80, 0)
    command("ACME_L1", "navigate", lat=away[0], lon=away[1])
    there = Drone.objects.filter(drone_id="ACME_L1", airborne=True)
    assert wait_for(lambda: metres((there.get().lat, there.get().lon), away) < 3, 30)
    # Its reservation's band, 10 to 20 m: the drone is above it, off its plan.
    Reservation.objects.create(
        organisation=world_tx.org, drone=there.get(), kind="command",
        legs=[[*away, *away, 10.0, 20.0, 0, 4e9]], starts_at="2026-01-01T00:00Z",
        ends_at="2099-01-01T00:00Z", airborne_by="2026-01-01T00:00Z", radius_m=2,
        horizontal_min_m=30, vertical_min_m=10, min_lat=0, max_lat=0, min_lon=0, max_lon=0,
    )  # fmt: skip
    time.sleep(4 * PASS_S)  # the band relayed
    # The link cut: the broker goes away (and comes back without the drone's password, so
    # the ground never hears it again: its own flight record is the evidence).
    sky.broker.restart(down_for=1.5)
    logs = drone.folder / "logs"
    assert wait_for(lambda: max((p[0] for p in flight_track(logs)), default=0) > 70, 60)
    track = flight_track(logs)
    far = max(range(len(track)), key=lambda k: track[k][0])
    homeward = [p for p in track[far:] if 5.0 < math.hypot(p[0], p[1]) < 75.0]
    assert len(homeward) > 10, track[far:]
    heights = [p[2] for p in homeward]
    assert 9.0 <= min(heights) and max(heights) <= 21.0, heights  # inside 10..20 m
    assert math.hypot(*track[-1][:2]) < 3.0 and track[-1][2] < 0.5  # landed at home

"""Ten simulated drones (the software flight controller and the real onboard agent) whose
homes are a few metres apart hover over them on separated layers and are all sent home at
once, by ten `return` commands through the REST API: the landing queue brings them down
one at a time, and their reported positions never show two airborne drones within the
separation minima (30 m horizontally while closer than 10 m vertically)."""

from __future__ import annotations

import itertools
import math
import threading
from concurrent.futures import ThreadPoolExecutor

import pytest
from asgiref.sync import async_to_sync
from django.db import connection

from airspace import landing
from airspace.models import LandingSlot
from fleet import commands, envelopes
from fleet.models import Drone
from tests.airspace.test_e2e import Track
from tests.missions.sky import Sky, metres
from tests.support.experiments import api, ground  # noqa: F401
from tests.support.ground import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

COUNT = 10
# Layers 14 m apart (the vertical minimum and twice the vertical tolerance): the tenth at
# 136 m, so the organisation's ceiling is raised to 160 m for this test.
LAYERS = [10.0 + 14.0 * i for i in range(COUNT)]


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    s = Sky(tmp_path, world_tx.org.slug, ground).start()
    yield s
    s.close()


class Turns(threading.Thread):
    """Stands in for Celery beat's `airspace.advance_landings`: the queue's pass, every
    half second, on the test database."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.done, self.landed = threading.Event(), []

    def run(self) -> None:
        try:
            while not self.done.wait(0.5):
                self.landed += landing.advance()
        finally:
            connection.close()


def command(user, drone_id: str, name: str, **params) -> dict:  # type: ignore[no-untyped-def]
    body = {"command": name, "params": params, "confirm_beyond_defaults": True}
    answer = api(user).post(f"/api/v1/drones/{drone_id}/commands/", body, format="json")
    assert answer.status_code == 200, (drone_id, name, answer.json())
    return answer.json()


def returned(user, drone_id: str) -> dict:  # type: ignore[no-untyped-def]
    try:
        return command(user, drone_id, "return")
    finally:
        connection.close()


def take_off_on_layers(world, sky: Sky, ids: list[str], settings) -> None:  # type: ignore[no-untyped-def]
    """Every drone up to its layer over its home. The climbs are not what is tested: they
    are sent with no minima (the suite's own), then the production minima come back."""
    minima = (settings.AIRSPACE_HORIZONTAL_MIN_M, settings.AIRSPACE_VERTICAL_MIN_M)
    radius = settings.AIRSPACE_CORRIDOR_RADIUS_M
    settings.AIRSPACE_HORIZONTAL_MIN_M = settings.AIRSPACE_VERTICAL_MIN_M = 0.0
    settings.AIRSPACE_CORRIDOR_RADIUS_M = 0.0
    try:
        # Through the command path itself (fleet/commands.py), without the HTTP round trip.
        for drone_id, layer in zip(ids, LAYERS, strict=True):
            for name, params in (("arm", {}), ("takeoff", {"altitude": layer})):
                sent = async_to_sync(commands.send)(world.operator, drone_id, name, params, True)
                assert sent.ok, (drone_id, name, sent.reply)
    finally:
        settings.AIRSPACE_HORIZONTAL_MIN_M, settings.AIRSPACE_VERTICAL_MIN_M = minima
        settings.AIRSPACE_CORRIDOR_RADIUS_M = radius

    def on_layers() -> bool:
        rows = Drone.objects.filter(drone_id__in=ids, airborne=True)
        heights = {d.drone_id: d.alt or 0.0 for d in rows}
        return len(heights) == COUNT and all(
            abs(heights[i] - layer) < 1.0 for i, layer in zip(ids, LAYERS, strict=True)
        )

    assert wait_for(on_layers, 60), sky.describe()


def test_ten_drones_sent_home_at_once_land_one_at_a_time_separated(world_tx, sky, settings):
    envelopes.set_envelope(world_tx.org, {"max_height": 160})
    ids = [f"ACME_Q{i}" for i in range(COUNT)]
    for i, drone_id in enumerate(ids):
        # Homes on a circle of 3 m around the origin: one landing site.
        angle = 2 * math.pi * i / COUNT
        sky.add_drone(drone_id, north=3 * math.cos(angle), east=3 * math.sin(angle))
    sky.wait_online()
    take_off_on_layers(world_tx, sky, ids, settings)

    track, turns = Track(ids), Turns()
    track.start()
    try:
        # Sent at once, the top first so that the first answered cannot simply go down.
        with ThreadPoolExecutor(COUNT) as pool:
            replies = list(pool.map(lambda d: returned(world_tx.operator, d), reversed(ids)))
        # The queue's passes start once every drone has its place: a drone given its turn
        # while the others still join (their returns take seconds on a loaded machine)
        # lands and leaves, and the places of those joining after it count one fewer.
        turns.start()
        assert all(r["ok"] for r in replies), replies
        queued = [r["result"]["queue"] for r in replies if "queue" in (r["result"] or {})]
        # At most one went home as before; every other one holds at its own layer.
        assert len(queued) >= COUNT - 1, replies
        # Places in order of arrival (after the one landing, if one went home as before).
        places = sorted(q["place"] for q in queued)
        assert places == list(range(COUNT - len(queued) + 1, COUNT + 1)), replies
        assert {q["layer_m"] for q in queued} <= set(LAYERS)
        assert len({q["layer_m"] for q in queued}) == len(queued)

        def all_down() -> bool:
            return not Drone.objects.filter(drone_id__in=ids, airborne=True).exists()

        assert wait_for(all_down, 180), sky.describe()
    finally:
        track.done.set()
        turns.done.set()
        track.join(5)
        if turns.ident is not None:  # started
            turns.join(5)

    together = [s for s in track.samples if len(s) >= 2]
    assert len(together) > 20, "the drones were never seen in the air together"
    for sample in together:
        for (a_id, a), (b_id, b) in itertools.combinations(sample.items(), 2):
            apart_h, apart_v = metres(a[:2], b[:2]), abs(a[2] - b[2])
            assert apart_h >= 30.0 or apart_v >= 10.0, (a_id, b_id, apart_h, apart_v)
    # The queue sent `land` to the held ones in turn, the lowest first (nothing under it).
    held = [i for i in ids if i in turns.landed]
    assert len(held) >= COUNT - 1 and turns.landed == sorted(turns.landed, key=ids.index)
    landing.advance()  # the pass after the last landing takes it out of the queue
    assert not LandingSlot.objects.filter(ended_at__isnull=True).exists()
    reasons = set(LandingSlot.objects.values_list("end_reason", flat=True))
    assert reasons == {"landed"}, reasons

"""A simulated drone (the software flight controller and the real onboard agent) flying a
mission north is sent home by the operator while another hovers low over the same home:
its part of the mission is stopped on the ground and on the drone, it flies no further
step, and it holds over home at its layer — the queue's pass sends the hold again should
the stop's own hold (sent with it) reach the drone after it."""

from __future__ import annotations

import pytest
from asgiref.sync import async_to_sync

from airspace.models import LandingSlot
from fleet import commands
from fleet.models import Drone
from missions.models import Event, MissionStatus
from tests.airspace.test_e2e import start
from tests.airspace.test_landing_e2e import Turns, command
from tests.missions.conftest import point_at
from tests.missions.sky import Sky, metres
from tests.support.experiments import api, ground, wait_status  # noqa: F401
from tests.support.ground import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def sky(world_tx, ground, tmp_path):  # type: ignore[no-untyped-def]  # noqa: F811
    # At 4x (not the suite's 20x): the mission's next waypoint must stay out of reach for
    # the ground's own latency (heartbeats, the REST call) between the return and the stop.
    s = Sky(tmp_path, world_tx.org.slug, ground, time_scale=4.0).start()
    yield s
    s.close()


# The ground's position of a drone lags behind it by its heartbeat (0.3 s) and more on a
# loaded machine (2 s seen): at 4x, 2 s is 80 m of a 10 m/s flight.
LAG_MARGIN_M = 80.0


def north_and_back() -> dict:
    far, farther = point_at(150.0, 3.0), point_at(300.0, 3.0)
    return {
        "name": "north",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 30}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": far[0], "lon": far[1]}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": farther[0], "lon": farther[1]}},
            {"command": "wait_for_flight"},
            {"command": "land"},
        ],
    }


def position(drone_id: str) -> tuple[float, float, float]:
    drone = Drone.objects.get(drone_id=drone_id)
    return drone.lat, drone.lon, drone.alt or 0.0


def test_a_return_stops_the_mission_and_the_drone_holds_over_home(world_tx, sky, settings):
    sky.add_drone("ACME_L")
    sky.add_drone("ACME_M", east=3.0)
    sky.wait_online()
    # Both up beside each other: what is tested is the way home, so they are sent with no
    # minima (the suite's own), then the production minima come back.
    minima = (settings.AIRSPACE_HORIZONTAL_MIN_M, settings.AIRSPACE_VERTICAL_MIN_M)
    radius = settings.AIRSPACE_CORRIDOR_RADIUS_M
    settings.AIRSPACE_HORIZONTAL_MIN_M = settings.AIRSPACE_VERTICAL_MIN_M = 0.0
    settings.AIRSPACE_CORRIDOR_RADIUS_M = 0.0
    try:
        for name, params in (("arm", {}), ("takeoff", {"altitude": 10})):
            sent = async_to_sync(commands.send)(world_tx.operator, "ACME_L", name, params, True)
            assert sent.ok, sent.reply
        mission_id, started = start(world_tx, north_and_back(), "ACME_M")
        assert started.status_code == 200, started.json()
    finally:
        settings.AIRSPACE_HORIZONTAL_MIN_M, settings.AIRSPACE_VERTICAL_MIN_M = minima
        settings.AIRSPACE_CORRIDOR_RADIUS_M = radius
    home = point_at(0.0, 3.0)
    assert wait_for(lambda: metres(position("ACME_M")[:2], home) > 30.0, 90), sky.describe()

    turns = Turns()
    turns.start()
    try:
        reply = command(world_tx.operator, "ACME_M", "return")
        answered_out = metres(position("ACME_M")[:2], home)
        # ACME_L hovers under it over the site: it is queued, at its own height (30 m is
        # 20 m above ACME_L's 10 m).
        # Flying a mission, it is sent `hold` first: its mission pauses where it is.
        assert reply["ok"] and reply["command"] == "hold", reply
        assert reply["result"]["queue"]["place"] == 1 and reply["result"]["queue"]["layer_m"] == 30
        assert wait_status(mission_id, {"stopped"}, 5).status == MissionStatus.STOPPED
        # The drone stops its mission too (it reports it), and flies to its hold.
        assert wait_for(
            lambda: Event.objects.filter(
                mission_id=mission_id, kind=Event.Kind.MISSION, data__status="stopped"
            ).exists(),
            30,
        ), sky.describe()

        farthest = [0.0]

        def holding() -> bool:
            lat, lon, alt = position("ACME_M")
            away = metres((lat, lon), home)
            farthest.append(away)
            return away < 3.0 and abs(alt - 30.0) < 2.0

        assert wait_for(holding, 90), (sky.describe(), list(LandingSlot.objects.values()))
    finally:
        turns.done.set()
        turns.join(5)
    # The drone stopped where it was when the return was answered (it had paused its
    # mission by then), give or take the ground's lag behind it, and flew no further step:
    # its mission's last waypoint, 300 m out, was never reached.
    assert max(farthest) < min(answered_out + LAG_MARGIN_M, 280.0), (answered_out, farthest)
    slot = LandingSlot.objects.get(drone__drone_id="ACME_M")
    assert slot.ended_at is None and slot.state == LandingSlot.State.HOLDING
    print(f"farthest out after the return {max(farthest):.0f} m; re-sent: {slot.hold_resends}")

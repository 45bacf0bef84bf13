"""End to end: two simulated drones (simulator + real onboard agent each), the broker, the
gateway, the database, and /control — nothing replaced."""

from __future__ import annotations

import json

import pytest

from fleet import credentials
from fleet.heartbeats import sweep_offline
from fleet.models import ConnectionEvent, Drone
from runtime.processes import wait_for

from .conftest import client_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

HEARTBEAT_S = 0.5
TIME_SCALE = 5.0
HOME = (38.736946, -9.142685, 100.0)
IDS = ("ACME_SIM1", "ACME_SIM2")


def start_fleet(tmp_path, broker_port: int, ids=IDS):  # type: ignore[no-untyped-def]
    """Provision the drones into the broker and start simulator + agent for each."""
    from firmware.sim.fleet import parse_credentials, plan_fleet

    issued = [credentials.provision(drone_id, "acme").to_dict() for drone_id in ids]
    fleet = plan_fleet(
        count=len(ids),
        home=HOME,
        workdir=tmp_path / "fleet",
        credentials=parse_credentials(json.dumps(issued)),
        broker_url=f"mqtt://127.0.0.1:{broker_port}",
        time_scale=TIME_SCALE,
        agent_args=["--heartbeat-interval", str(HEARTBEAT_S)],
    )
    fleet.start()
    return fleet


@pytest.fixture
def fleet(world_tx, broker, gateway, tmp_path, settings):  # type: ignore[no-untyped-def]
    settings.HEARTBEAT_INTERVAL_S = HEARTBEAT_S
    running = start_fleet(tmp_path, broker.port)
    try:
        online = wait_for(
            lambda: (
                Drone.objects.filter(drone_id__in=IDS, online=True, lat__isnull=False)
                .exclude(specs={})
                .count()
                == len(IDS)
            ),
            timeout=30,
            interval=0.1,
        )
        assert online, "both simulated drones came online with their gear and a position"
        yield running
    finally:
        running.stop()


def control(client, **params: str) -> tuple[int, dict]:
    method = (
        client.get if params["command"] in ("discover", "getgear", "objrequest") else client.post
    )
    response = method("/control", params)
    return response.status_code, response.json()


def test_two_simulated_drones_are_discovered_and_flown_through_control(world_tx, fleet):
    from accounts import tokens

    client = client_for(world_tx.operator)
    # objrequest by GET sends a command: only an operate token may (fleet/control.py).
    client.defaults["HTTP_AUTHORIZATION"] = f"Token {tokens.issue(world_tx.operator).key}"

    status, body = control(client, command="discover")
    assert status == 200
    found = {d["drone_id"]: d for d in body["result"]["drones"]}
    assert set(IDS) <= set(found)
    for drone_id in IDS:
        assert found[drone_id]["online"] is True
        assert found[drone_id]["specs"]["TYPE"] == "HEXACOPTER"
        assert found[drone_id]["position"] is not None

    drone_id = IDS[0]
    for params in (
        {"command": "arm"},
        {"command": "takeoff", "altitude": "5"},
        {"command": "navigate", "lat": "38.7372", "lon": "-9.1425"},
        {"command": "land"},
    ):
        status, body = control(client, droneID=drone_id, **params)
        assert status == 200, (params, body)
        assert body["ok"] is True and len(body["request_id"]) == 32

    status, body = control(client, command="objrequest", droneID=drone_id, value="FlightStatus")
    assert status == 200, body
    assert body["result"]


def test_a_drone_killed_mid_flight_goes_offline_within_three_heartbeats_and_comes_back(
    world_tx, fleet
):
    client = client_for(world_tx.operator)
    victim = fleet.drones[1]
    assert control(client, command="arm", droneID=victim.drone_id)[0] == 200
    assert control(client, command="takeoff", droneID=victim.drone_id, altitude="5")[0] == 200
    assert wait_for(
        lambda: Drone.objects.filter(drone_id=victim.drone_id, airborne=True).exists(), 15
    )

    victim.agent.kill()  # SIGKILL, as a crash: no goodbye message

    def offline() -> bool:
        sweep_offline()  # what Celery beat runs every OFFLINE_SWEEP_INTERVAL_S
        return not Drone.objects.get(drone_id=victim.drone_id).online

    assert wait_for(offline, timeout=10, interval=0.1)
    last_seen = Drone.objects.get(drone_id=victim.drone_id).last_seen
    went_offline = ConnectionEvent.objects.get(drone__drone_id=victim.drone_id, kind="offline").at
    # Three missed heartbeats after the last one, plus this loop's polling period and the
    # sweep's own time: measured 1.59-1.60 s quiet and 1.52-1.61 s with four busy processes
    # on two cores, against 1.8 s.
    assert (went_offline - last_seen).total_seconds() <= 3 * HEARTBEAT_S + 0.3
    assert Drone.objects.get(drone_id=IDS[0]).online, "the other drone is unaffected"
    status, body = control(client, command="land", droneID=victim.drone_id)
    assert status == 409 and "offline" in body["error"]

    fleet.restart_agent(victim)
    assert wait_for(
        lambda: Drone.objects.filter(drone_id=victim.drone_id, online=True).exists(), 20
    )
    kinds = list(
        ConnectionEvent.objects.filter(drone__drone_id=victim.drone_id)
        .order_by("pk")
        .values_list("kind", flat=True)
    )
    assert kinds == ["online", "offline", "online"]

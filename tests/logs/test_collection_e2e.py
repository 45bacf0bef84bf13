"""End to end: a simulated flight of each protocol through the real ground (web, gateway,
telemetry ingest, Celery worker and beat on a private Mosquitto) — a MAVLink PX4 drone
and a UAVTalk one, each the simulator and the real onboard agent. After landing their
logs arrive by themselves (the onboard DFI recording of both; the PX4's own ULog fetched
over MAVLink's log protocol), are imported and checked, and the flight's record lists them."""

from __future__ import annotations

import pytest

from firmware.sim.fleet import start_drone
from tests.missions.planning import point_at
from tests.support.ground import HOME_ALT_MSL, Api, mosquitto_ground, wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# Records close 1 s after the disarm; imports go to the ground's own worker queue.
ENV = {"RECORDS_CLOSE_DELAY_S": "1", "RECORDS_SETTLE_INTERVAL_S": "1", "LOGS_IMPORT_QUEUE": ""}
PX4, UAVTALK = "ACME_LOGPX4", "ACME_LOGUAV"


def _start(ground, drone_id: str, slug: str, fc: str, north: float, **sim):  # type: ignore[no-untyped-def]
    url = ground.provision(drone_id, slug)
    lat, lon = point_at(north, 0.0)
    web = ground.processes.web_urls[0]
    args = ["--heartbeat-interval", "0.3", "--ground-url", web, "--uplink", "wifi"]
    drone = start_drone(
        ground.directory / drone_id, drone_id, url, (lat, lon, HOME_ALT_MSL),
        time_scale=ground.time_scale, fc=fc, agent_args=args, **sim,
    )  # fmt: skip
    ground.drones[drone_id] = drone


def _fly(api: Api, drone_id: str) -> None:
    for command, params in (("arm", {}), ("takeoff", {"altitude": 6}), ("land", {})):
        reply = api.post(
            f"/api/v1/drones/{drone_id}/commands/", {"command": command, "params": params}
        )
        assert reply.status_code == 200 and reply.json()["ok"], (drone_id, command, reply.text)
        if command == "takeoff":
            assert wait_for(lambda: (_drone(drone_id).alt or 0) > 5.0, 30), drone_id
    assert wait_for(lambda: not _drone(drone_id).airborne, 40), drone_id
    if _drone(drone_id).armed:
        api.post(f"/api/v1/drones/{drone_id}/commands/", {"command": "disarm"})


def _drone(drone_id: str):  # type: ignore[no-untyped-def]
    from fleet.models import Drone

    return Drone.objects.get(drone_id=drone_id)


def _ready_logs(drone_id: str) -> list:
    from logs.models import CollectedLog

    rows = CollectedLog.objects.filter(drone__drone_id=drone_id).select_related("log")
    return [r for r in rows if r.log is not None and r.log.status == "ready"]


def test_each_protocols_flight_uploads_its_logs_and_its_record_lists_them(
    world_tx, tmp_path, settings
):
    from records.models import FlightRecord

    with mosquitto_ground(
        tmp_path, settings, web=1, gateways=1, ingests=1, workers=1, env=ENV
    ) as ground:
        slug = world_tx.org.slug
        _start(ground, PX4, slug, "mavlink", 0.0, extra_args=["--autopilot", "px4"])
        _start(ground, UAVTALK, slug, "uavtalk", -150.0)
        ground.wait_online([PX4, UAVTALK])
        api = Api(world_tx.operator, ground.processes.web_urls)
        _fly(api, PX4)
        _fly(api, UAVTALK)

        def arrived() -> bool:
            return len(_ready_logs(PX4)) == 2 and len(_ready_logs(UAVTALK)) == 1

        assert wait_for(arrived, 120), ground.processes.describe()
        assert wait_for(lambda: FlightRecord.objects.count() == 2, 60)
        flights = {f["drone"]: f for f in api.get("/api/v1/flights/").json()["results"]}
        listed = {
            drone_id: {
                (entry["kind"], entry["format"]): entry
                for entry in api.get(f"/api/v1/flights/{flights[drone_id]['id']}/").json()["logs"]
            }
            for drone_id in (PX4, UAVTALK)
        }
        checks = {
            (drone_id, *key): api.get(entry["checks"]).json()["checks"]
            for drone_id in listed
            for key, entry in listed[drone_id].items()
        }

    assert set(listed[PX4]) == {("onboard", "dfi"), ("fc", "ulog")}, listed
    assert set(listed[UAVTALK]) == {("onboard", "dfi")}, listed
    # Every log checked on arrival (a report with every check, whatever the format) ...
    assert all(len(found) >= 8 for found in checks.values()), checks
    # ... and the PX4's own log carries the topics the checks read.
    assert len(checks) == 3
    fc_checks = {c["name"]: c for c in checks[(PX4, "fc", "ulog")]}
    assert fc_checks["gps"]["status"] == "pass", fc_checks["gps"]
    assert fc_checks["battery_sag"]["status"] != "not_checked", fc_checks["battery_sag"]
    assert all(
        c["status"] in ("pass", "warning", "fail", "not_checked") for c in fc_checks.values()
    )

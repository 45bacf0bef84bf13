"""End to end with a simulated dRonin (UAVTalk) drone, which reports no battery serial: an
operator names a pack and fits it before flight, flies the drone by hand through the
real ground, and the flight's record names the pack, which counts the flight."""

from __future__ import annotations

import pytest

from tests.support.ground import Api, mosquitto_ground, wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_BATU"
# The records process closes a flight 1 s after it is seen disarmed.
RECORDS_ENV = {"RECORDS_CLOSE_DELAY_S": "1", "RECORDS_SETTLE_INTERVAL_S": "1"}


def _drone(name: str) -> object:
    from fleet.models import Drone

    return getattr(Drone.objects.get(drone_id=DRONE), name)


def test_a_chosen_pack_is_named_by_the_flight_and_counts_it(world_tx, tmp_path, settings):
    from batteries.models import Battery
    from records.models import FlightRecord

    with mosquitto_ground(
        tmp_path, settings, web=1, gateways=1, ingests=1, workers=1, env=RECORDS_ENV
    ) as ground:
        ground.add_drone(DRONE, world_tx.org.slug)
        ground.wait_online([DRONE])
        api = Api(world_tx.operator, ground.processes.web_urls)
        made = api.post("/api/v1/batteries/", {"serial": "PACK-U1", "rated_energy_wh": 81.4})
        assert made.status_code == 201, made.text
        chosen = api.request(
            "PUT", f"/api/v1/drones/{DRONE}/battery/", {"battery": made.json()["id"]}
        )
        assert chosen.status_code == 200 and chosen.json()["reported_serial"] is None, chosen.text
        for command, params in (("arm", {}), ("takeoff", {"altitude": 5}), ("land", {})):
            reply = api.post(
                f"/api/v1/drones/{DRONE}/commands/", {"command": command, "params": params}
            )
            assert reply.status_code == 200 and reply.json()["ok"], (command, reply.text)
            if command == "takeoff":
                assert wait_for(lambda: (_drone("alt") or 0.0) > 4.0, 30)
        assert wait_for(lambda: not _drone("airborne"), 30)
        if _drone("armed"):
            api.post(f"/api/v1/drones/{DRONE}/commands/", {"command": "disarm"})
        assert wait_for(lambda: FlightRecord.objects.filter(drone_ident=DRONE).exists(), 60), (
            ground.processes.describe()
        )

    record = FlightRecord.objects.get(drone_ident=DRONE)
    assert record.battery == "PACK-U1"
    pack = Battery.objects.get(serial="PACK-U1")
    assert pack.flights == 1 and pack.drone.drone_id == DRONE and not pack.reported
    assert pack.cycles == pytest.approx(record.battery_start - record.battery_end, abs=1e-3)
    assert pack.energy_wh == pytest.approx(record.energy_wh, abs=1e-3) and pack.energy_wh > 0
    assert pack.uses.get().record_id == record.pk

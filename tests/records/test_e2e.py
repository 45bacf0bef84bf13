"""End to end: simulated drones (simulator + the real onboard agent) fly through the real
ground (web, gateway, telemetry ingest, Celery worker and beat on a private Mosquitto);
each flight becomes one record, checked against the telemetry the ingest stored."""

from __future__ import annotations

import math
from datetime import timedelta

import pytest

from fleet.models import Role
from tests import factories
from tests.missions.planning import point_at
from tests.support.ground import Api, mosquitto_ground, wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

ALTITUDE = 10.0
NORTH, EAST = 40.0, 30.0
# The ground's records process closes a flight 1 s after it is seen disarmed; the beat
# catches up every second.
RECORDS_ENV = {"RECORDS_CLOSE_DELAY_S": "1", "RECORDS_SETTLE_INTERVAL_S": "1"}
# Tolerances: the figures are recomputed here from the same stored samples, so they must
# agree closely; the flown geometry is the mission's within the waypoint tolerance of
# wait_for_flight (2 m) and the simulator's overshoot.
SAME_SAMPLES = 0.05
GEOMETRY_M = 5.0


def _mission_steps() -> list[dict]:
    first, second = point_at(NORTH, 0.0), point_at(NORTH, EAST)
    return [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": ALTITUDE}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": first[0], "lon": first[1]}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": second[0], "lon": second[1]}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "land", "params": {}},
    ]


def _stored(drone_pk: int, start, end) -> list[tuple[float, str, dict]]:  # type: ignore[no-untyped-def]
    from django.db import connection

    with connection.cursor() as cursor:
        cursor.execute(
            "SELECT extract(epoch FROM ts)::float8, object, fields || coalesce(labels, '{}') "
            "FROM telemetry_sample WHERE drone_id = %s AND ts >= %s AND ts <= %s ORDER BY ts",
            [drone_pk, start, end],
        )
        return [(ts, name, _json(fields)) for ts, name, fields in cursor.fetchall()]


def _json(value):  # type: ignore[no-untyped-def]
    import json

    return json.loads(value) if isinstance(value, str) else value


def _independent_figures(samples: list) -> dict:
    """The figures straight from the samples: every position step counted, the power
    integrated sample to sample."""
    positions = [f for _, n, f in samples if n == "PositionActual"]
    path = sum(
        math.hypot(b["North"] - a["North"], b["East"] - a["East"])
        for a, b in zip(positions, positions[1:], strict=False)
    )
    power = [(t, f["Voltage"] * f["Current"]) for t, n, f in samples if n == "FlightBatteryState"]
    energy = sum((b[0] - a[0]) * (a[1] + b[1]) / 2 for a, b in zip(power, power[1:], strict=False))
    return {
        "path_m": path,
        "max_height_m": max(-f["Down"] for f in positions),
        "max_distance_m": max(math.hypot(f["North"], f["East"]) for f in positions),
        "energy_wh": energy / 3600,
    }


def _armed_span(record) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """When the drone's own FlightStatus samples say it armed and disarmed, read from the
    stored telemetry around the record."""
    around = timedelta(seconds=30)
    samples = _stored(record.drone_id, record.started_at - around, record.ended_at + around)
    changes = [(t, f["Armed"]) for t, n, f in samples if n == "FlightStatus"]
    armed = next(t for t, state in changes if state == "Armed")
    disarmed = next(t for t, state in changes if t > armed and state == "Disarmed")
    return armed, disarmed


def _check_against_telemetry(record) -> None:  # type: ignore[no-untyped-def]
    armed, disarmed = _armed_span(record)
    assert record.started_at.timestamp() == pytest.approx(armed, abs=0.001)
    assert record.duration_s == pytest.approx(disarmed - armed, abs=0.1)
    samples = _stored(record.drone_id, record.started_at, record.ended_at)
    found = _independent_figures(samples)
    assert record.max_height_m == pytest.approx(found["max_height_m"], abs=0.01)
    assert record.max_distance_m == pytest.approx(found["max_distance_m"], abs=0.01)
    # Steps under 0.2 m are merged, so the record's path is never longer, and nearly equal.
    assert found["path_m"] * (1 - SAME_SAMPLES) <= record.distance_m <= found["path_m"] + 0.01
    assert record.energy_method == "voltage_current"
    assert record.energy_wh == pytest.approx(found["energy_wh"], rel=SAME_SAMPLES)
    assert record.battery_start > record.battery_end


def test_a_mission_and_a_manual_flight_make_one_record_each(world_tx, tmp_path, settings):
    from records.models import FlightRecord, Origin

    with mosquitto_ground(
        tmp_path, settings, web=1, gateways=1, ingests=1, workers=1, env=RECORDS_ENV
    ) as ground:
        ground.add_drone("ACME_REC1", world_tx.org.slug)
        ground.add_drone("ACME_REC2", world_tx.org.slug, north=-150.0, east=-150.0)
        ground.wait_online(["ACME_REC1", "ACME_REC2"])
        api = Api(world_tx.operator, ground.processes.web_urls)
        created = api.post("/api/v1/missions/", {"name": "records", "steps": _mission_steps()})
        assert created.status_code == 201, created.text
        mission_id = created.json()["id"]
        started = api.post(f"/api/v1/missions/{mission_id}/start/", {"drone": "ACME_REC1"})
        assert started.status_code == 200, started.text

        # Another operator flies the second drone by hand.
        pilot = factories.person(world_tx.org, Role.OPERATOR, "fieldpilot")
        manual = Api(pilot, ground.processes.web_urls)
        for command, params in (
            ("arm", {}),
            ("takeoff", {"altitude": 6}),
            ("land", {}),
        ):
            reply = manual.post(
                "/api/v1/drones/ACME_REC2/commands/", {"command": command, "params": params}
            )
            assert reply.status_code == 200 and reply.json()["ok"], (command, reply.text)
            if command == "takeoff":
                assert wait_for(lambda: _height("ACME_REC2") > 5.0, 30)
        # Landed: the drone disarms by itself (auto-disarm), or by command once down.
        assert wait_for(lambda: not _flag("ACME_REC2", "airborne"), 30)
        if _flag("ACME_REC2", "armed"):
            manual.post("/api/v1/drones/ACME_REC2/commands/", {"command": "disarm"})

        def recorded() -> bool:
            return FlightRecord.objects.count() == 2

        assert wait_for(recorded, 120), ground.processes.describe()
        mission_flight = FlightRecord.objects.get(drone_ident="ACME_REC1")
        manual_flight = FlightRecord.objects.get(drone_ident="ACME_REC2")

    assert str(mission_flight.mission_id) == mission_id
    assert (mission_flight.origin, mission_flight.pilot) == (Origin.MISSION, world_tx.operator)
    assert mission_flight.max_height_m == pytest.approx(ALTITUDE, abs=1.0)
    assert mission_flight.max_distance_m == pytest.approx(math.hypot(NORTH, EAST), abs=GEOMETRY_M)
    assert mission_flight.distance_m == pytest.approx(NORTH + EAST, abs=2 * GEOMETRY_M)
    _check_against_telemetry(mission_flight)

    assert (manual_flight.origin, manual_flight.pilot) == (Origin.COMMAND, pilot)
    assert manual_flight.pilot_name == "fieldpilot"
    assert manual_flight.mission is None
    assert manual_flight.max_height_m == pytest.approx(6.0, abs=1.0)
    assert manual_flight.takeoff_at is not None and manual_flight.landing_at is not None
    _check_against_telemetry(manual_flight)


def _flag(drone_id: str, name: str) -> bool:
    from fleet.models import Drone

    return bool(getattr(Drone.objects.get(drone_id=drone_id), name))


def _height(drone_id: str) -> float:
    from fleet.models import Drone

    return Drone.objects.get(drone_id=drone_id).alt or 0.0

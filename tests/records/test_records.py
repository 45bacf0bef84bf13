"""Flight records from stored telemetry: figures, attribution, append-only corrections,
the API with its filters and organisation isolation, logbook totals and CSV export."""

from __future__ import annotations

import csv
import io
import math
from datetime import timedelta

import pytest
from django.test import Client
from rest_framework.test import APIClient

from fleet.models import CommandLog
from records import building
from records.figures import AIRBORNE_HEIGHT_M
from records.models import EnergyMethod, FlightRecord, OpenFlight, Origin

from .support import CLIMB_S, HEIGHT_M, days_ago, flight_samples, fly, store

pytestmark = pytest.mark.django_db


def _api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def test_a_flight_is_recorded_from_its_stored_telemetry(world):
    record, flown = fly(world.drone, days_ago(1))
    # The drone's FlightStatus samples bound the flight, not the heartbeats seen 0.4 s late.
    assert abs(record.started_at.timestamp() - flown.armed) < 0.01
    assert abs(record.duration_s - (flown.disarmed - flown.armed)) < 0.15
    assert abs(record.distance_m - flown.distance_m) < 1.0
    assert abs(record.max_height_m - flown.max_height_m) < 0.01
    assert abs(record.max_distance_m - flown.max_distance_m) < 0.01
    assert abs(record.max_speed_ms - flown.max_speed_ms) < 0.01
    assert record.energy_method == EnergyMethod.VOLTAGE_CURRENT
    assert record.energy_wh == pytest.approx(flown.energy_wh, rel=0.02)
    assert record.takeoff_at is not None and record.landing_at is not None
    # Above 0.5 m from the climb's first quarter second to the descent's last (2 m/s).
    climb_rate = HEIGHT_M / CLIMB_S
    airborne = 2 * CLIMB_S + 28.0 - 2 * AIRBORNE_HEIGHT_M / climb_rate
    assert record.airborne_s == pytest.approx(airborne, abs=0.15)
    assert record.origin == Origin.UNKNOWN and record.pilot is None
    assert record.track and record.track[0][0] >= 0
    assert not OpenFlight.objects.exists()


def test_closing_again_changes_nothing(world):
    samples, flown = flight_samples(world.drone.pk, days_ago(1))
    store(samples)
    from .support import at

    opened = building.open_flight(world.drone, at(flown.armed))
    assert building.open_flight(world.drone, at(flown.armed + 1)) is None  # one per drone
    building.mark_disarmed(world.drone, at(flown.disarmed))
    first = building.close_flight(opened.pk)
    assert building.close_flight(opened.pk) is None
    assert FlightRecord.objects.count() == 1 and first is not None


def test_without_power_samples_energy_comes_from_capacity_and_charge(world):
    from .support import at

    drone = world.drone
    drone.specs = {"BATTERY": {"CELL_COUNT": 4, "CAPACITY": 5000}}
    drone.battery_remaining, drone.battery_voltage = 0.9, 16.2
    drone.save()
    samples, flown = flight_samples(drone.pk, days_ago(1))
    store([s for s in samples if s.object != "FlightBatteryState"])
    opened = building.open_flight(drone, at(flown.armed))
    drone.battery_remaining, drone.battery_voltage = 0.7, 15.8
    drone.save()
    building.mark_disarmed(drone, at(flown.disarmed))
    record = building.close_flight(opened.pk)
    assert record.energy_method == EnergyMethod.CAPACITY_CHARGE
    # 5 Ah × 20 % × the mean of the voltages seen (16.2 V and 15.8 V).
    assert record.energy_wh == pytest.approx(5.0 * 0.2 * 16.0, rel=1e-6)
    assert (record.battery_start, record.battery_end) == (0.9, 0.7)


def test_the_operator_who_armed_it_is_the_pilot(world):
    armed = days_ago(1)
    from .support import at

    CommandLog.objects.create(
        drone=world.drone,
        user=world.operator,
        request_id="r1",
        command="arm",
        outcome=CommandLog.Outcome.OK,
        sent_at=at(armed - 1.0),
    )
    record, _ = fly(world.drone, armed)
    assert record.origin == Origin.COMMAND
    assert record.pilot == world.operator and record.pilot_name == "operator"


def test_a_mission_flight_names_its_mission_and_who_started_it(world):
    from missions.models import Assignment, Event, Mission

    mission = Mission.objects.create(organisation=world.org, name="Survey", created_by=world.owner)
    assignment = Assignment.objects.create(mission=mission, drone=world.drone, step_indexes=[0])
    Event.objects.create(
        mission=mission, kind=Event.Kind.DECISION, data={"decision": "start", "user": "operator"}
    )
    samples, flown = flight_samples(world.drone.pk, days_ago(1))
    store(samples)
    from .support import at

    opened = building.open_flight(
        world.drone,
        at(flown.armed),
        {"mission_id": str(mission.pk), "assignment_id": str(assignment.pk), "index": 0},
    )
    building.mark_disarmed(world.drone, at(flown.disarmed))
    record = building.close_flight(opened.pk)
    assert (record.origin, record.pilot, record.mission) == (
        Origin.MISSION,
        world.operator,
        mission,
    )

    replacement = Assignment.objects.create(
        mission=mission, drone=world.drone, step_indexes=[0], reason=Assignment.Reason.REPLACEMENT
    )
    later = days_ago(0.5)
    samples, flown = flight_samples(world.drone.pk, later)
    store(samples)
    opened = building.open_flight(
        world.drone,
        at(later),
        {"mission_id": str(mission.pk), "assignment_id": str(replacement.pk)},
    )
    building.mark_disarmed(world.drone, at(flown.disarmed))
    record = building.close_flight(opened.pk)
    assert (record.origin, record.pilot) == (Origin.PLATFORM, None)


def test_alarms_during_the_flight_are_its_events(world):
    from alerts.models import Alert

    from .support import at

    armed = days_ago(1)
    Alert.objects.create(
        organisation=world.org, kind=Alert.Kind.CRITICAL_ALARM, severity="critical",
        title="CRITICAL alarm from ACME_1: Outside the flight envelope: too high",
        drone_id="ACME_1", source="alarm:x", at=at(armed + 20),
    )  # fmt: skip
    Alert.objects.create(
        organisation=world.org, kind=Alert.Kind.CRITICAL_ALARM, severity="critical",
        title="before", drone_id="ACME_1", source="alarm:y", at=at(armed - 60),
    )  # fmt: skip
    from fleet.models import ConnectionEvent
    from missions.models import Event, Mission

    mission = Mission.objects.create(organisation=world.org, name="Survey")
    Event.objects.create(
        mission=mission, drone=world.drone, kind=Event.Kind.ALARM, at=at(armed + 25),
        message="battery below 25 % (24 % left)", data={"level": "CRITICAL"},
    )  # fmt: skip
    ConnectionEvent.objects.create(
        drone=world.drone, kind="offline", at=at(armed + 30), reason="no heartbeat for 15.0 s"
    )
    record, _ = fly(world.drone, armed)
    assert [(e["kind"], e["message"]) for e in record.events] == [
        ("alert", "CRITICAL alarm from ACME_1: Outside the flight envelope: too high"),
        ("failsafe", "battery below 25 % (24 % left)"),
        ("link", "Offline: no heartbeat for 15.0 s"),
    ]
    client = Client()
    client.force_login(world.viewer)
    page = client.get(f"/records/flights/{record.pk}/").content.decode()
    assert "Outside the flight envelope: too high" in page
    assert at(armed + 20).strftime("%H:%M:%S") in page


# -- append-only, corrections ------------------------------------------------------------


def test_records_cannot_be_changed_or_deleted(world):
    record, _ = fly(world.drone, days_ago(1))
    record.distance_m = 1.0
    with pytest.raises(PermissionError):
        record.save()
    with pytest.raises(PermissionError):
        record.delete()
    with pytest.raises(PermissionError):
        FlightRecord.objects.filter(pk=record.pk).update(distance_m=1.0)
    with pytest.raises(PermissionError):
        FlightRecord.objects.filter(pk=record.pk).delete()
    admin_client = _api(world.owner)
    url = f"/api/v1/flights/{record.pk}/"
    assert admin_client.patch(url, {"distance_m": 1}, format="json").status_code == 405
    assert admin_client.put(url, {"distance_m": 1}, format="json").status_code == 405
    assert admin_client.delete(url).status_code == 405


def test_corrections_append_a_new_record_naming_the_old(world):
    record, _ = fly(world.drone, days_ago(1))
    url = f"/api/v1/flights/{record.pk}/corrections/"
    body = {"reason": "flown by the operator from the field", "pilot": "operator", "battery": "P7"}
    assert _api(world.operator).post(url, body, format="json").status_code == 403
    assert _api(world.viewer).post(url, body, format="json").status_code == 403
    assert _api(world.outsider).post(url, body, format="json").status_code == 404
    response = _api(world.owner).post(url, body, format="json")
    assert response.status_code == 201, response.content
    new = response.json()
    assert new["corrects"] == record.pk and new["pilot"] == "operator" and new["battery"] == "P7"
    assert new["distance_m"] == record.distance_m  # the rest is copied
    old = FlightRecord.objects.get(pk=record.pk)
    assert old.pilot is None and old.distance_m == record.distance_m  # unchanged
    # The list shows each flight once, in its current version; `all` shows both.
    listed = _api(world.viewer).get("/api/v1/flights/").json()["results"]
    assert [f["id"] for f in listed] == [new["id"]]
    both = _api(world.viewer).get("/api/v1/flights/?all=true").json()["results"]
    assert {f["id"] for f in both} == {record.pk, new["id"]}
    assert _api(world.owner).post(url, body, format="json").status_code == 409
    bad = _api(world.owner).post(
        f"/api/v1/flights/{new['id']}/corrections/",
        {"reason": "x", "distance_m": -5},
        format="json",
    )
    assert bad.status_code == 400 and bad.json()["fields"].keys() == {"distance_m"}
    unknown = _api(world.owner).post(
        f"/api/v1/flights/{new['id']}/corrections/",
        {"reason": "x", "pilot": "outsider"},
        format="json",
    )
    assert unknown.status_code == 400 and "pilot" in unknown.json()["error"]
    no_reason = _api(world.owner).post(
        f"/api/v1/flights/{new['id']}/corrections/", {"battery": "P8"}, format="json"
    )
    assert no_reason.status_code == 400
    assert FlightRecord.objects.count() == 2


# -- the API -----------------------------------------------------------------------------


def test_the_api_filters_and_isolates_organisations(world):
    from tests import factories

    first, _ = fly(world.drone, days_ago(40))
    second, _ = fly(world.drone, days_ago(2))
    other, _ = fly(world.other_drone, days_ago(2))
    viewer = _api(world.viewer)
    listed = viewer.get("/api/v1/flights/").json()
    assert [f["id"] for f in listed["results"]] == [second.pk, first.pk]
    flight = listed["results"][0]
    for key in ("started_at", "ended_at", "duration_s", "distance_m", "max_height_m",
                "max_distance_m", "battery_start", "battery_end", "energy_wh", "battery",
                "pilot", "mission", "events"):  # fmt: skip
        assert key in flight
    assert flight["battery"] is None
    since = (second.started_at - timedelta(days=1)).date().isoformat()
    assert [f["id"] for f in viewer.get(f"/api/v1/flights/?since={since}").json()["results"]] == [
        second.pk
    ]
    until = (first.started_at + timedelta(days=1)).date().isoformat()
    assert [f["id"] for f in viewer.get(f"/api/v1/flights/?until={until}").json()["results"]] == [
        first.pk
    ]
    assert viewer.get("/api/v1/flights/?drone=GLOBEX_1").json()["results"] == []
    assert viewer.get("/api/v1/flights/?pilot=operator").json()["results"] == []
    assert viewer.get("/api/v1/flights/?since=yesterday").status_code == 400
    assert viewer.get("/api/v1/flights/?mission=nope").status_code == 400
    assert viewer.get(f"/api/v1/flights/{other.pk}/").status_code == 404
    detail = viewer.get(f"/api/v1/flights/{first.pk}/").json()
    assert detail["track"] and detail["samples"] > 0
    outsider = _api(world.outsider).get("/api/v1/flights/").json()["results"]
    assert [f["id"] for f in outsider] == [other.pk]
    stranger = factories.person(None, username="stranger")
    assert _api(stranger).get("/api/v1/flights/").json()["results"] == []
    assert APIClient().get("/api/v1/flights/").status_code in (401, 403)


def test_the_schema_documents_the_flights_api(world):
    schema = _api(world.viewer).get("/api/schema/?format=json").json()
    assert "/api/v1/flights/" in schema["paths"]
    assert "/api/v1/flights/{id}/corrections/" in schema["paths"]
    names = {p["name"] for p in schema["paths"]["/api/v1/flights/"]["get"]["parameters"]}
    assert {"drone", "pilot", "mission", "since", "until"} <= names


# -- logbooks ----------------------------------------------------------------------------


def _csv(response) -> list[dict]:  # type: ignore[no-untyped-def]
    text = b"".join(response.streaming_content).decode()
    return list(csv.DictReader(io.StringIO(text)))


def test_three_flights_make_three_records_and_the_logbook_totals(world, settings):
    settings.TIME_ZONE = "UTC"
    from .support import at

    armed = [days_ago(400), days_ago(35), days_ago(3)]
    for t in armed:
        CommandLog.objects.create(
            drone=world.drone, user=world.operator, request_id=f"r{t}", command="arm",
            outcome=CommandLog.Outcome.OK, sent_at=at(t - 1.0),
        )  # fmt: skip
    flights = [fly(world.drone, t) for t in armed]
    assert FlightRecord.objects.filter(drone=world.drone).count() == 3
    client = Client()
    client.force_login(world.viewer)
    page = client.get("/records/drones/ACME_1/?period=year")
    assert page.status_code == 200
    overall = page.context["overall"]
    hours = sum(r.duration_s for r, _ in flights) / 3600
    assert overall.flights == 3 and overall.hours == pytest.approx(hours, abs=1e-3)
    assert overall.distance_m == pytest.approx(sum(r.distance_m for r, _ in flights), abs=0.2)
    years = {t.period.year: t.flights for t in page.context["totals"]}
    assert sum(years.values()) == 3 and years == _count_by(armed, "%Y")
    months = {
        t.period.strftime("%Y-%m"): t.flights
        for t in client.get("/records/pilots/operator/?period=month").context["totals"]
    }
    assert months == _count_by(armed, "%Y-%m")
    rows = _csv(client.get("/records/pilots/operator/?format=csv"))
    assert [int(r["id"]) for r in rows] == [r.pk for r, _ in reversed(flights)]
    newest = flights[-1][0]
    assert rows[0]["drone"] == "ACME_1" and rows[0]["pilot"] == "operator"
    assert float(rows[0]["duration_s"]) == newest.duration_s
    assert float(rows[0]["distance_m"]) == newest.distance_m
    assert rows[0]["started_at"] == newest.started_at.isoformat()
    assert rows[0]["energy_method"] == "voltage_current"
    assert client.get("/records/drones/ACME_1/?period=week").status_code == 404
    assert client.get("/records/drones/GLOBEX_1/").status_code == 404
    assert client.get("/records/pilots/outsider/").status_code == 404
    detail = client.get(f"/records/flights/{newest.pk}/")
    assert detail.status_code == 200 and b"flight-track" in detail.content
    assert client.get(f"/records/flights/{newest.pk + 999}/").status_code == 404


def _count_by(epochs: list[float], fmt: str) -> dict:
    from .support import at

    out: dict = {}
    for t in epochs:
        key = at(t).strftime(fmt)
        key = int(key) if fmt == "%Y" else key
        out[key] = out.get(key, 0) + 1
    return out


def test_the_csv_export_is_bounded(world, settings):
    settings.RECORDS_EXPORT_MAX_ROWS = 2
    for days in (5, 4, 3):
        fly(world.drone, days_ago(days))
    client = Client()
    client.force_login(world.owner)
    rows = _csv(client.get("/records/drones/ACME_1/?format=csv"))
    assert len(rows) == 2


def test_another_organisation_sees_nothing_in_the_logbooks(world):
    fly(world.drone, days_ago(1))
    client = Client()
    client.force_login(world.outsider)
    assert client.get("/records/drones/ACME_1/").status_code == 404
    record = FlightRecord.objects.get()
    assert client.get(f"/records/flights/{record.pk}/").status_code == 404
    own = client.get("/records/drones/GLOBEX_1/")
    assert own.status_code == 200 and own.context["overall"].flights == 0
    assert not math.isnan(own.context["overall"].hours)


# -- how flights are opened and closed ---------------------------------------------------


def _beat(drone_id: str, **fields: object):  # type: ignore[no-untyped-def]
    import time

    from onboard.protocol import parse_heartbeat

    message = {
        "type": "heartbeat", "drone_id": drone_id, "ts": time.time(),
        "position": {"lat": 40.6303, "lon": -8.6575, "alt": 0.0},
        "battery": {"voltage": 16.4, "remaining": 0.9}, "armed": False, "airborne": False,
        "flight_mode": "POSITIONHOLD", "mission": None,
        "fc": {"protocol": "uavtalk", "connected": True},
    }  # fmt: skip
    message.update(fields)
    return parse_heartbeat(message)


def test_heartbeats_open_and_mark_flights_and_the_sweep_closes_them(world, settings):
    from fleet.heartbeats import handle_heartbeats

    settings.RECORDS_CLOSE_DELAY_S = 0.0
    handle_heartbeats([("ACME_1", _beat("ACME_1"))])
    assert not OpenFlight.objects.exists()
    mission = {"mission_id": "not-a-mission", "assignment_id": "nor-an-assignment", "index": 0}
    handle_heartbeats([("ACME_1", _beat("ACME_1", armed=True, mission=mission))])
    handle_heartbeats([("ACME_1", _beat("ACME_1", armed=True, airborne=True))])
    flight = OpenFlight.objects.get()
    assert flight.disarmed_at is None and flight.mission == mission
    assert flight.start["battery_remaining"] == 0.9
    handle_heartbeats([("ACME_1", _beat("ACME_1", battery={"voltage": 15.9, "remaining": 0.7}))])
    flight.refresh_from_db()
    assert flight.disarmed_at is not None and flight.end["battery_remaining"] == 0.7
    assert building.reconcile()["closed"] == 1
    record = FlightRecord.objects.get()
    assert (record.battery_start, record.battery_end) == (0.9, 0.7)
    assert record.samples == 0 and record.distance_m is None and record.origin == Origin.UNKNOWN


def test_the_sweep_catches_up_with_arming_it_did_not_hear(world, settings):
    from django.utils import timezone

    settings.RECORDS_CLOSE_DELAY_S = 0.0
    drone = world.drone
    drone.armed, drone.online = True, True
    drone.last_seen = timezone.now() - timedelta(seconds=40)
    drone.save()
    assert building.reconcile() == {"opened": 1, "marked": 0, "closed": 0}
    assert building.reconcile() == {"opened": 0, "marked": 0, "closed": 0}
    drone.armed, drone.last_seen = False, timezone.now() - timedelta(seconds=10)
    drone.save()
    assert building.reconcile() == {"opened": 0, "marked": 1, "closed": 1}
    assert FlightRecord.objects.get().duration_s == pytest.approx(30.0, abs=0.5)


def test_malformed_filters_answer_400_or_404_not_500(world):
    viewer = _api(world.viewer)
    for name in ("drone", "pilot", "mission", "since", "until"):
        for value in ("\x00", "ACME_1\x00", "2026-13-45T99:99", "x" * 300):
            response = viewer.get("/api/v1/flights/", {name: value})
            assert response.status_code in (200, 400), (name, value, response.status_code)
    client = Client(raise_request_exception=False)
    client.force_login(world.viewer)
    for value in ("\x00", "2026-13-45", "-1"):
        for query in ({"pilot": value}, {"since": value}, {"page": value}, {"period": value}):
            response = client.get("/records/drones/ACME_1/", query)
            # A NUL anywhere in a query is refused before the view (config/urlchars.py).
            expected = (400,) if "\x00" in value else (200, 404)
            assert response.status_code in expected, (query, response.status_code)


def test_a_drone_lost_while_armed_ends_its_flight_at_its_last_heartbeat(world, settings):
    from django.utils import timezone

    settings.RECORDS_CLOSE_DELAY_S = 0.0
    settings.RECORDS_LOST_AFTER_S = 60.0
    drone = world.drone
    drone.armed, drone.online, drone.last_seen = True, True, timezone.now() - timedelta(minutes=5)
    drone.save()
    assert building.reconcile()["opened"] == 1
    drone.online, drone.last_seen = False, timezone.now() - timedelta(seconds=90)
    drone.save()
    assert building.reconcile() == {"opened": 0, "marked": 1, "closed": 1}
    record = FlightRecord.objects.get()
    assert record.duration_s == pytest.approx(210.0, abs=1.0)
    assert [e["kind"] for e in record.events] == ["lost"]
    # Still armed and offline: no new flight opens for it.
    assert building.reconcile() == {"opened": 0, "marked": 0, "closed": 0}


@pytest.mark.django_db(transaction=True)
def test_closing_a_flight_locks_neither_its_drone_nor_another_close(world_tx):
    """While one process computes a flight, heartbeats still update its drone, and a second
    close of the same flight passes it by instead of waiting."""
    import psycopg
    from django.db import transaction
    from django.utils import timezone

    from telemetry.queries import conninfo_from_settings

    now = timezone.now()
    flight = OpenFlight.objects.create(
        drone=world_tx.drone,
        organisation=world_tx.org,
        armed_at=now - timedelta(minutes=2),
        disarmed_at=now - timedelta(minutes=1),
    )
    with transaction.atomic():
        assert building.lock_disarmed(flight.pk) is not None
        with psycopg.connect(conninfo_from_settings(), autocommit=True) as other:
            other.execute("SET lock_timeout = '2s'")
            other.execute(
                "UPDATE fleet_drone SET battery_remaining = 0.5 WHERE id = %s",
                [world_tx.drone.pk],
            )
            skipped = other.execute(
                "SELECT id FROM records_openflight WHERE id = %s FOR UPDATE SKIP LOCKED",
                [flight.pk],
            ).fetchall()
            assert skipped == []

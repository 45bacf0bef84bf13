"""Batteries from flight records made the ground's way (stored telemetry, open on
arming, close): cycles over flights, health and retirement, the drone refused, the API's
isolation and its refusals of bad input."""

from __future__ import annotations

import pytest
from rest_framework.test import APIClient

from batteries.health import SagEstimator
from batteries.models import Battery, BatteryPolicy
from records import building
from tests.records.support import at, days_ago, flight_samples, store

pytestmark = pytest.mark.django_db

# The synthetic flight draws 10 A at 16 V for its 52 s: 2.31 Wh (tests/records/support.py).
SOC_DROPS = (0.30, 0.25, 0.20)


def _api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def _fly(drone, armed: float, start: float, end: float):  # type: ignore[no-untyped-def]
    """One flight whose heartbeats report `start` then `end` state of charge."""
    samples, flown = flight_samples(drone.pk, armed)
    store(samples)
    drone.battery_remaining = start
    drone.save(update_fields=["battery_remaining"])
    opened = building.open_flight(drone, at(armed))
    drone.battery_remaining = end
    drone.save(update_fields=["battery_remaining"])
    building.mark_disarmed(drone, at(flown.disarmed))
    return building.close_flight(opened.pk)


def _choose(world, name: str, rated_wh: float) -> dict:  # type: ignore[no-untyped-def]
    client = _api(world.operator)
    made = client.post(
        "/api/v1/batteries/", {"serial": name, "rated_energy_wh": rated_wh}, format="json"
    )
    assert made.status_code == 201, made.content
    chosen = client.put(
        f"/api/v1/drones/{world.drone.drone_id}/battery/",
        {"battery": made.json()["id"]},
        format="json",
    )
    assert chosen.status_code == 200, chosen.content
    assert chosen.json()["battery"]["serial"] == name
    return made.json()


def test_cycles_are_counted_across_three_flights(world):
    pack = _choose(world, "PACK-A", rated_wh=10.0)
    start = 1.0
    records = []
    for i, drop in enumerate(SOC_DROPS):
        records.append(_fly(world.drone, days_ago(3 - i), start, start - drop))
        start = 1.0  # charged again before the next flight
    assert all(r.battery == "PACK-A" for r in records)
    battery = Battery.objects.get(pk=pack["id"])
    # Equivalent full cycles: the state-of-charge drops summed [SBS 1.1, CycleCount()].
    assert battery.flights == 3
    assert battery.cycles == pytest.approx(sum(SOC_DROPS))
    assert battery.energy_wh == pytest.approx(sum(r.energy_wh for r in records), rel=1e-3)
    # Capacity per flight = energy / drop; health = median over the rated 10 Wh.
    capacities = sorted(r.energy_wh / d for r, d in zip(records, SOC_DROPS, strict=True))
    assert battery.capacity_wh == pytest.approx(capacities[1], rel=1e-3)
    assert battery.health == pytest.approx(capacities[1] / 10.0, abs=1e-3)
    # The flights API names the pack; the battery API shows the totals and the flights.
    client = _api(world.viewer)
    flights = client.get("/api/v1/flights/", {"drone": world.drone.drone_id}).json()["results"]
    assert {f["battery"] for f in flights} == {"PACK-A"}
    detail = client.get(f"/api/v1/batteries/{pack['id']}/").json()
    assert detail["flights"] == 3 and len(detail["uses"]) == 3
    assert detail["cycles"] == pytest.approx(0.75) and detail["age_days"] >= 0


def test_a_worn_battery_is_retired_and_its_drone_refused(world):
    # 2.31 Wh for a 25 % drop: the pack holds 9.2 Wh of its rated 20 (health 46 %).
    pack = _choose(world, "PACK-W", rated_wh=20.0)
    record = _fly(world.drone, days_ago(1), 0.9, 0.65)
    worn = f"health {record.energy_wh / 0.25 / 20.0:.0%} below 80%"
    battery = Battery.objects.get(pk=pack["id"])
    assert battery.retired and battery.retired_reason == worn
    world.drone.online = True
    world.drone.save(update_fields=["online"])
    client = _api(world.operator)
    verdict = client.get(f"/api/v1/drones/{world.drone.drone_id}/airworthiness/").json()
    assert verdict["airworthy"] is False
    assert f"battery PACK-W retired: {worn}" in verdict["reasons"]
    response = client.post(
        f"/api/v1/drones/{world.drone.drone_id}/commands/",
        {"command": "arm", "params": {}},
        format="json",
    )
    assert response.status_code == 409, response.content
    assert response.json()["code"] == "not_airworthy"
    assert "PACK-W" in response.json()["error"]
    # A lower threshold (admins) puts it back in service.
    admin = _api(world.owner)
    changed = admin.put(
        f"/api/v1/organisations/{world.org.slug}/battery-policy/",
        {"health_threshold": 0.4},
        format="json",
    )
    assert changed.status_code == 200 and changed.json()["health_threshold"] == 0.4
    assert not Battery.objects.get(pk=pack["id"]).retired
    # A cycle limit below its 0.25 cycles retires it again.
    admin.put(
        f"/api/v1/organisations/{world.org.slug}/battery-policy/",
        {"cycle_limit": 0.2},
        format="json",
    )
    assert "0.2 cycles above the limit of 0.2" in Battery.objects.get(pk=pack["id"]).retired_reason


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"cycle_limit": -1}, "cycle_limit"),
        ({"health_threshold": 1.5}, "health_threshold"),
        ({"health_threshold": -0.1}, "health_threshold"),
        ({"health_threshold": "high"}, "health_threshold"),
        ({"health_threshold": 0.5, "cycle_limt": 3}, "cycle_limt"),
    ],
)
def test_bad_rules_are_refused_naming_the_field(world, body, field):
    response = _api(world.owner).put(
        f"/api/v1/organisations/{world.org.slug}/battery-policy/", body, format="json"
    )
    assert response.status_code == 400 and field in response.json()["fields"], response.content
    assert not BatteryPolicy.objects.exists()


def test_bad_choices_are_refused_and_change_nothing(world):
    pack = _choose(world, "PACK-B", rated_wh=50.0)
    client = _api(world.operator)
    foreign = Battery.objects.create(organisation=world.other_org, serial="GLOBEX-PACK")
    url = f"/api/v1/drones/{world.drone.drone_id}/battery/"
    for battery in (999_999, foreign.pk, "x"):
        response = client.put(url, {"battery": battery}, format="json")
        assert response.status_code == 400 and "battery" in response.json()["fields"], (
            response.content
        )
    assert Battery.objects.get(pk=pack["id"]).drone_id == world.drone.pk
    bad = client.post(
        "/api/v1/batteries/", {"serial": "PACK-C", "rated_energy_wh": -5}, format="json"
    )
    assert bad.status_code == 400 and "rated_energy_wh" in bad.json()["fields"]
    twice = client.post("/api/v1/batteries/", {"serial": "PACK-B"}, format="json")
    assert twice.status_code == 400 and "serial" in twice.json()["fields"]
    assert not Battery.objects.filter(serial="PACK-C").exists()
    # A drone whose flight controller names its pack cannot be given another.
    world.drone.fc = {"battery_serial": "SMART-1"}
    world.drone.save(update_fields=["fc"])
    refused = client.put(url, {"battery": pack["id"]}, format="json")
    assert refused.status_code == 400 and "SMART-1" in refused.json()["fields"]["battery"][0]


def test_roles_and_organisations(world):
    pack = _choose(world, "PACK-R", rated_wh=50.0)
    assert _api(world.outsider).get(f"/api/v1/batteries/{pack['id']}/").status_code == 404
    listed = _api(world.outsider).get("/api/v1/batteries/").json()["results"]
    assert [b["serial"] for b in listed] == []
    viewer = _api(world.viewer)
    assert viewer.get("/api/v1/batteries/").json()["results"][0]["serial"] == "PACK-R"
    assert viewer.post("/api/v1/batteries/", {"serial": "V"}, format="json").status_code == 403
    assert (
        viewer.patch(
            f"/api/v1/batteries/{pack['id']}/", {"rated_energy_wh": 60}, format="json"
        ).status_code
        == 403
    )
    operator = _api(world.operator)
    assert (
        operator.put(
            f"/api/v1/organisations/{world.org.slug}/battery-policy/",
            {"cycle_limit": 3},
            format="json",
        ).status_code
        == 403
    )
    assert operator.get(f"/api/v1/drones/{world.other_drone.drone_id}/battery/").status_code == 404


def test_internal_resistance_from_voltage_sag():
    """V = OCV − I·R at current steps (take-off, landing) gives R back."""
    sag = SagEstimator()
    ocv, resistance = 16.4, 0.025
    for t, current in enumerate([1.0, 1.0, 20.0, 21.0, 20.5, 35.0, 20.0, 3.0, 3.0]):
        sag.add(t * 0.5, ocv - 0.001 * t - current * resistance, current)
    assert sag.result() == pytest.approx(resistance, rel=0.05)


def test_the_rules_form_of_the_batteries_page(world):
    from django.test import Client

    admin, operator = Client(), Client()
    admin.force_login(world.owner)
    operator.force_login(world.operator)
    refused = admin.post("/batteries/rules/", {"health_threshold": "1.5"}, follow=True)
    assert "health_threshold: must be between 0 and 1" in refused.content.decode()
    assert not BatteryPolicy.objects.exists()
    assert operator.post("/batteries/rules/", {"health_threshold": "0.7"}).status_code == 404
    admin.post("/batteries/rules/", {"health_threshold": "0.7", "cycle_limit": "300"})
    rules = BatteryPolicy.objects.get(organisation=world.org)
    assert (rules.health_threshold, rules.cycle_limit) == (0.7, 300.0)
    page = admin.get("/batteries/").content.decode()
    assert 'id="battery-rules"' in page and "below 70 %" in page
    assert 'id="battery-rules"' not in operator.get("/batteries/").content.decode()

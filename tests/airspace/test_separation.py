"""Separation between the organisation's own drones, on the real database: a flight
within the minima of another drone's reservation is refused with 409 `conflict` naming
the other drone, the place and the time; reservations end when their drone lands or its
mission stops; the platform's own split of an area flies on separated layers."""

from __future__ import annotations

import re
from datetime import datetime

import pytest
from rest_framework.test import APIClient

from airspace import reservations, separation
from airspace.index import Airspace, Flight, Reserved
from airspace.models import Reservation, SeparationMinima
from fleet.models import Drone, Organisation
from missions import collaboration
from missions.creation import create_mission
from missions.handover import Assignment as PlannedPart
from missions.handover import Handover
from missions.models import Assignment, Mission
from missions.planning import coverage, mission_steps
from missions.startstop import start_mission
from tests.airspace.scenes import failing_over_origin, replace
from tests.missions.conftest import online_drone, point_at, rectangle
from tests.missions.test_services import _alarm_event

pytestmark = pytest.mark.django_db
PLACE = re.compile(r"at (-?\d+\.\d+), (-?\d+\.\d+) from (\S+)\.$")


def client_for(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def crossing(start: tuple[float, float], end: tuple[float, float], altitude: float) -> dict:
    """Take off at home and climb to `altitude` before leaving (a navigate sent while
    still climbing is flown on a slant: test_slant.py), fly from `start` to `end` (north,
    east metres), land."""
    a, b = point_at(*start), point_at(*end)
    return {
        "name": f"{start} → {end}",
        "steps": [
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": altitude}},
            {"command": "wait_for_flight"},
            {"command": "navigate", "params": {"lat": a[0], "lon": a[1]}},
            {"command": "navigate", "params": {"lat": b[0], "lon": b[1]}},
            {"command": "land"},
        ],
    }


def start(user, body: dict, drone_id: str):  # type: ignore[no-untyped-def]
    client = client_for(user)
    created = client.post("/api/v1/missions/", body, format="json")
    assert created.status_code == 201, created.json()
    return client.post(
        f"/api/v1/missions/{created.json()['id']}/start/", {"drone": drone_id}, format="json"
    )


@pytest.fixture
def two_drones(world):  # type: ignore[no-untyped-def]
    """ACME_A 150 m south of the origin, ACME_B 150 m west, both on the ground."""
    online_drone(world.org, "ACME_A", north=-150)
    online_drone(world.org, "ACME_B", east=-150)
    return world


def test_a_mission_crossing_another_at_its_height_and_time_is_refused_naming_it(two_drones):
    world = two_drones
    first = start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A")
    assert first.status_code == 200, first.json()
    before = datetime.now().astimezone()
    second = start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B")
    assert second.status_code == 409, second.json()
    error = second.json()
    assert error["code"] == "conflict" and "drone ACME_A" in error["error"], error
    lat, lon, at = PLACE.search(error["error"]).groups()
    origin = point_at(0, 0)
    # The legs cross at the origin; the time is within the first minutes of both flights.
    assert abs(float(lat) - origin[0]) < 1e-5 and abs(float(lon) - origin[1]) < 1e-5
    assert -1 <= (datetime.fromisoformat(at) - before).total_seconds() < 120
    assert Mission.objects.filter(status="draft").count() == 1
    assert not Assignment.objects.filter(drone__drone_id="ACME_B").exists()


def test_the_same_crossing_twenty_metres_higher_is_accepted(two_drones):
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    second = start(world.operator, crossing((0, -150), (0, 150), 40), "ACME_B")
    assert second.status_code == 200, second.json()
    assert Reservation.objects.filter(ended_at__isnull=True).count() == 2


def test_a_panic_call_across_another_drones_corridor_is_refused(two_drones):
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    caller = point_at(0, 100)
    # ACME_B, the one available, would fly from 150 m west to the caller at 10 m,
    # across ACME_A's corridor at 20 m: bands 6 m apart.
    refused = client_for(world.operator).post(
        "/api/v1/missions/panic/", {"lat": caller[0], "lon": caller[1]}, format="json"
    )
    assert refused.status_code == 409, refused.json()
    assert refused.json()["code"] == "conflict" and "drone ACME_A" in refused.json()["error"]
    assert Mission.objects.count() == 1


def test_an_organisations_own_minima_apply(two_drones):
    world = two_drones
    SeparationMinima.objects.create(organisation=world.org, horizontal_m=30.0, vertical_m=25.0)
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    second = start(world.operator, crossing((0, -150), (0, 150), 40), "ACME_B")
    assert second.status_code == 409 and "25 m vertically" in second.json()["error"]


def test_a_navigate_command_into_another_drones_corridor_is_refused(two_drones):
    world = two_drones
    assert start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A").status_code == 200
    home = point_at(0, -150)
    Drone.objects.filter(drone_id="ACME_B").update(
        airborne=True, alt=20.0, home=list(home), lat=home[0], lon=home[1]
    )
    target = point_at(0, 150)
    refused = client_for(world.operator).post(
        "/api/v1/drones/ACME_B/commands/",
        {"command": "navigate", "params": {"lat": target[0], "lon": target[1]}},
        format="json",
    )
    assert refused.status_code == 409, refused.json()
    assert refused.json()["code"] == "conflict" and "drone ACME_A" in refused.json()["error"]
    # Well clear of the corridor (west, away from it) it is not refused for separation.
    away = point_at(0, -250)
    response = client_for(world.operator).post(
        "/api/v1/drones/ACME_B/commands/",
        {"command": "navigate", "params": {"lat": away[0], "lon": away[1]}},
        format="json",
    )
    assert response.json().get("code") != "conflict", response.json()


def active() -> list[Reservation]:
    return list(Reservation.objects.filter(ended_at__isnull=True))


def test_a_reservation_ends_when_its_mission_stops_or_its_drone_lands(two_drones):
    world = two_drones
    client = client_for(world.operator)
    started = start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A")
    mission_id = started.json()["id"]
    listed = client.get(f"/api/v1/organisations/{world.org.slug}/reservations/").json()
    assert [r["drone_id"] for r in listed["reservations"]] == ["ACME_A"]
    assert client.post(f"/api/v1/missions/{mission_id}/stop/").status_code == 200
    listed = client.get(f"/api/v1/organisations/{world.org.slug}/reservations/").json()
    assert listed["reservations"] == []
    assert Reservation.objects.get().end_reason == "plan ended"

    # Stopped, the drone's corridor is free for ACME_B, which then flies and lands.
    assert start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B").status_code == 200
    Drone.objects.filter(drone_id="ACME_B").update(airborne=True, alt=20.0)
    assert (
        len(
            client.get(f"/api/v1/organisations/{world.org.slug}/reservations/").json()[
                "reservations"
            ]
        )
        == 1
    )
    Drone.objects.filter(drone_id="ACME_B").update(airborne=False, alt=0.0)
    assert (
        client.get(f"/api/v1/organisations/{world.org.slug}/reservations/").json()["reservations"]
        == []
    )
    assert Reservation.objects.get(drone__drone_id="ACME_B").end_reason == "landed"


def test_the_reservations_endpoint_lists_corridors_bands_and_windows_to_members_only(two_drones):
    world = two_drones
    start(world.operator, crossing((-150, 0), (150, 0), 20), "ACME_A")
    body = client_for(world.viewer).get(f"/api/v1/organisations/{world.org.slug}/reservations/")
    assert body.status_code == 200, body.json()
    (reservation,) = body.json()["reservations"]
    assert reservation["drone_id"] == "ACME_A" and reservation["kind"] == "mission"
    assert body.json()["separation_m"] == {"horizontal": 30.0, "vertical": 10.0}
    climb, south, cruise, descent = reservation["legs"]
    assert cruise["band_m"] == [18.0, 22.0] and cruise["radius_m"] == 2.0
    assert cruise["start"] == pytest.approx(list(point_at(-150, 0)))
    assert cruise["end"] == pytest.approx(list(point_at(150, 0)))
    assert cruise["window"][0] < cruise["window"][1]
    outsider = client_for(world.outsider)
    assert outsider.get(f"/api/v1/organisations/{world.org.slug}/reservations/").status_code == 404
    theirs = outsider.get(f"/api/v1/organisations/{world.other_org.slug}/reservations/")
    assert theirs.status_code == 200 and theirs.json()["reservations"] == []
    schema = client_for(world.viewer).get("/api/schema/", HTTP_ACCEPT="application/json").json()
    assert "/api/v1/organisations/{slug}/reservations/" in schema["paths"]


def _part(drone_id: str, home: tuple, far: tuple, first_index: int) -> PlannedPart:
    """Take off at home and climb to its layer before leaving, as the platform's own parts
    do (missions/handover.py), fly across to `far` and back home at the takeoff's height,
    land."""
    a, b = point_at(*far), point_at(*home)
    steps = [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": 20.0}},
        {"command": "wait_for_flight", "params": {}},
        {"command": "navigate", "params": {"lat": a[0], "lon": a[1]}},
        {"command": "navigate", "params": {"lat": b[0], "lon": b[1]}},
        {"command": "land", "params": {}},
    ]
    steps = [{"index": first_index + i, **step} for i, step in enumerate(steps)]
    return PlannedPart(drone_id, "collaboration", steps, [first_index, first_index + 1])


def _split() -> Handover:
    parts = [
        _part("ACME_A", (-150, 0), (150, 0), 10),
        _part("ACME_B", (0, -150), (0, 150), 20),
    ]
    return Handover(parts, [s for p in parts for s in p.steps], [])


def _takeoffs(plan: Handover) -> dict[str, float]:
    return {
        part.drone_id: next(
            s["params"]["altitude"] for s in part.steps if s["command"] == "takeoff"
        )
        for part in plan.assignments
    }


def test_the_platforms_own_split_over_two_drones_gets_separated_layers(two_drones):
    drones = list(Drone.objects.filter(drone_id__in=["ACME_A", "ACME_B"]).order_by("drone_id"))
    plan = separation.layered_handover(_split(), drones)
    # ACME_A keeps the plan's 20 m; ACME_B's legs cross them at the same time, so it
    # climbs one layer higher: 10 m vertical minimum + 2 × 2 m band tolerance.
    assert _takeoffs(plan) == {"ACME_A": 20.0, "ACME_B": 34.0}
    stored = {s["index"]: s for s in plan.new_steps}
    assert stored[21]["params"]["altitude"] == 34.0 and stored[11]["params"]["altitude"] == 20.0
    legs = {
        part.drone_id: reservations.planned_legs(by_id, part.steps)[0]
        for part in plan.assignments
        for by_id in drones
        if by_id.drone_id == part.drone_id
    }
    other = Reserved("a", "ACME_A", 1, [leg.to_list() for leg in legs["ACME_A"]], 2.0, 30.0, 10.0)
    assert Airspace([other]).first_conflict(Flight(legs["ACME_B"], 2.0, 30.0, 10.0)) is None


def test_a_split_with_no_clear_layer_under_the_ceiling_waits_or_is_refused(two_drones, settings):
    world = two_drones
    Organisation.objects.filter(pk=world.org.pk).update(envelope={"max_height": 30.0})
    drones = list(Drone.objects.filter(drone_id__in=["ACME_A", "ACME_B"]).order_by("drone_id"))
    # No layer under the ceiling: ACME_B waits on the ground at the plan's height until
    # ACME_A's crossing is behind it, its wait a new step before its arm.
    plan = separation.layered_handover(_split(), drones)
    assert _takeoffs(plan) == {"ACME_A": 20.0, "ACME_B": 20.0}
    waiting = plan.assignments[1]
    assert waiting.steps[0]["command"] == "sleep" and waiting.steps[0]["params"]["value"] > 0
    assert waiting.preparation_indexes[0] == waiting.steps[0]["index"]
    assert [s["index"] for s in plan.new_steps] == list(range(10, 23))
    # Nor a wait within the longest allowed: refused.
    settings.AIRSPACE_STAGGER_MAX_S = waiting.steps[0]["params"]["value"] - 10
    with pytest.raises(separation.Conflict) as refused:
        separation.layered_handover(_split(), drones)
    assert refused.value.code == "conflict" and "drone ACME_A" in refused.value.message


def test_a_collaboration_whose_parts_layers_cannot_separate_is_staggered_or_declined(
    world, outbox, settings
):
    """The collaborative-sensing experiment's area ([Paula 2018], §5.4) is split into
    parts 7 m apart, each landing where it ends: with 30 m minima their landings come
    down through each other's layers. The joining drone waits on the ground until the
    alarming drone's part is clear of it; without staggered departures the extension is
    declined and nothing is sent."""
    area = coverage(rectangle(35, 28), 7)
    alarming = online_drone(world.org, "ACME_A", north=-10)
    online_drone(world.org, "ACME_B", north=-70, east=20)
    mission = create_mission(
        organisation=world.org,
        name="co2",
        steps=mission_steps(area.waypoints, altitude=10),
        extensibility={"vectors": area.vectors.to_dict(), "step_distance": 7},
    )
    assignment = start_mission(mission, drone=alarming).assignment
    Drone.objects.filter(pk=alarming.pk).update(airborne=True, alt=10.0)
    outbox.clear()
    alarm = _alarm_event(mission, alarming, level="OUT_MEASURE", north=14)
    settings.AIRSPACE_STAGGER_MAX_S = 0
    created = collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    assert created == []
    decision = mission.events.get(data__decision="collaboration_failed")
    assert "separation minima" in decision.message and "drone ACME_A" in decision.message
    assert outbox.items() == []
    decision.delete()
    settings.AIRSPACE_STAGGER_MAX_S = 600.0
    created = collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    joining = next(a for a in created if a.drone.drone_id == "ACME_B")
    first = mission.steps.get(index=joining.preparation[0])
    assert first.command == "sleep" and first.params["value"] > 0


def test_site_wide_another_organisations_drone_counts_and_is_not_named(world, settings):
    settings.AIRSPACE_SITE_WIDE = True
    online_drone(world.other_org, "GLOBEX_A", north=-150)
    online_drone(world.org, "ACME_B", east=-150)
    assert start(world.outsider, crossing((-150, 0), (150, 0), 20), "GLOBEX_A").status_code == 200
    refused = start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B")
    assert refused.status_code == 409 and refused.json()["code"] == "conflict"
    assert "a drone of another organisation" in refused.json()["error"]
    assert "GLOBEX" not in refused.json()["error"]
    listed = client_for(world.operator).get(f"/api/v1/organisations/{world.org.slug}/reservations/")
    assert listed.json()["reservations"] == []
    settings.AIRSPACE_SITE_WIDE = False
    assert start(world.operator, crossing((0, -150), (0, 150), 20), "ACME_B").status_code == 200


def test_a_replacement_flying_to_where_the_failing_drone_hovers_climbs_a_layer(world):
    """The failing drone hovers at 10 m where it stopped; its replacement's leg ends
    there, so it flies one layer up (24 m) rather than into the column under it."""
    failing, mission, assignment, alarm = failing_over_origin(world, -20.0)
    replacing = replace(mission, assignment, alarm)
    assert replacing is not None and replacing.drone.drone_id == "ACME_B"
    takeoff = mission.steps.get(index__in=replacing.preparation, command="takeoff")
    assert takeoff.params["altitude"] == 24.0
    reserved = Reservation.objects.get(assignment=replacing, ended_at__isnull=True)
    assert max(leg[5] for leg in reserved.legs) == 26.0
    # The failing drone's way down (10 m at 2 m/s) is reserved, not a hover of minutes.
    down = Reservation.objects.get(drone=failing, ended_at__isnull=True)
    assert down.command == "land" and [leg[4:6] for leg in down.legs] == [[0.0, 12.0]]
    assert (down.ends_at - down.starts_at).total_seconds() == pytest.approx(5 * 1.5 + 60)

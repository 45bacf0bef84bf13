"""The platform's own split of an area (a collaboration), decided on the real database:
where altitude layers cannot separate its parts (a landing comes down through every layer
under it) the joining drone's departure is staggered instead of the split being refused;
a part is never sent to a drone on the ground without the steps to take off again; and a
mission whose drone refuses a step never stays running."""

from __future__ import annotations

import pytest

from airspace import reservations
from airspace.corridors import Leg, Pace, flight_legs, offset
from airspace.index import Airspace, Flight, Reserved
from airspace.models import Reservation, SeparationMinima
from airspace.stagger import Search, lay, lay_plainly
from fleet.models import Drone, Organisation
from missions import collaboration
from missions.creation import create_mission
from missions.models import Assignment, Event, Mission, MissionStatus
from missions.progress import apply_progress
from missions.startstop import start_mission
from onboard import protocol
from tests.airspace.scenes import failing_over_origin, replace
from tests.missions.conftest import online_drone, point_at
from tests.missions.test_services import _alarm_event, _complete, _progress
from tests.support.experiments import survey_with_alarm

pytestmark = pytest.mark.django_db
ALARMING, JOINING = "ACME_SPLIT1", "ACME_SPLITM2"


def test_a_wait_on_the_ground_delays_the_flights_windows_by_all_of_it():
    """Flight times are shrunk for a fast drone (early 0.5); a wait before take-off is the
    drone's own timer and is not."""
    pace = Pace(speed_m_s=5.0, climb_m_s=2.0, early=0.5, slack=0.5, buffer_s=30.0)
    flight = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10.0}}]
    at_once, _ = flight_legs(flight, (40.0, -8.0, 0.0), 1000.0, pace)
    waiting, airborne_by = flight_legs(
        [{"command": "sleep", "params": {"value": 60}}, *flight], (40.0, -8.0, 0.0), 1000.0, pace
    )
    assert waiting[0].t0 - at_once[0].t0 == 60.0
    assert waiting[0].t1 - at_once[0].t1 == 90.0  # its end still stretched by the slack
    assert airborne_by == 1000.0 + 60 * 1.5 + 30.0
    # A hover in the air is flight time like any other: shrunk.
    hover = flight_legs(
        [{"command": "sleep", "params": {"value": 60}}], (40.0, -8.0, 10.0), 0, pace
    )
    assert hover[0][0].t1 - hover[0][0].t0 == 60 * 1.5 + 30 - (-30.0)


def _split_mission(world, alarming_north: float = 0.0, alarming_east: float = 60.0):  # type: ignore[no-untyped-def]
    """A survey flown by ACME_SPLIT1 at 10 m, rows 40 m apart, extended around an alarm
    after its second waypoint (40 m east of the origin); ACME_SPLIT1 is by then flying on
    towards its third, at `alarming_east`; ACME_SPLITM2 waits 150 m south."""
    SeparationMinima.objects.create(organisation=world.org, horizontal_m=15.0, vertical_m=10.0)
    alarming = online_drone(world.org, ALARMING, north=-10)
    online_drone(world.org, JOINING, north=-150)
    steps, extensibility = survey_with_alarm("OUT_MEASURE", 160, 80, 40, after=2)
    extensibility["intermediate_action"] = None
    mission = create_mission(
        organisation=world.org, name="split", steps=steps, extensibility=extensibility
    )
    assignment = start_mission(mission, drone=alarming).assignment
    _complete(alarming, mission, assignment, list(range(0, 6)))
    here = point_at(alarming_north, alarming_east)
    Drone.objects.filter(pk=alarming.pk).update(airborne=True, alt=10.0, lat=here[0], lon=here[1])
    alarm = _alarm_event(mission, alarming, level="OUT_MEASURE", north=0)
    alarm.data["position"] = dict(zip(("lat", "lon"), point_at(0, 40), strict=True), alt=10.0)
    alarm.save()
    return mission, assignment, alarm


def _collaborate(mission, assignment, alarm) -> list[Assignment]:  # type: ignore[no-untyped-def]
    return collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )


def _lift(commands: list[str]) -> list[str]:
    """The first two commands after a staggered departure's wait, if any."""
    return commands[1:3] if commands[0] == "sleep" else commands[:2]


def _steps_of(part: Assignment) -> list:  # type: ignore[type-arg]
    indexes = [*part.preparation, *part.step_indexes]
    by_index = {s.index: s for s in part.mission.steps.filter(index__in=indexes)}
    return [by_index[i] for i in indexes]


def test_a_landing_where_the_alarming_drone_flies_is_solved_by_a_staggered_departure(world, outbox):
    """The joining drone's part ends by landing where the alarming drone is now: a
    landing comes down through every layer, so no layer is clear at once. The joining
    drone waits on the ground before it arms instead, and both parts are sent."""
    mission, assignment, alarm = _split_mission(world)
    highest = mission.steps.order_by("-index").first().index
    parts = {p.drone.drone_id: p for p in _collaborate(mission, assignment, alarm)}
    assert sorted(parts) == [ALARMING, JOINING], list(
        mission.events.values_list("message", flat=True)
    )
    joining = _steps_of(parts[JOINING])
    assert [s.command for s in joining[:4]] == ["sleep", "arm", "takeoff", "wait_for_flight"]
    delay = joining[0].params["value"]
    assert 0 < delay <= 600 and delay % 10 == 0
    assert parts[JOINING].preparation == [s.index for s in joining[:4]]
    # The plan's own height is kept: the wait separates them.
    assert joining[2].params["altitude"] == 10.0
    # New steps are numbered in flying order, part by part, none skipped or reused.
    new = sorted(mission.steps.filter(index__gt=highest).values_list("index", flat=True))
    assert new == list(range(highest + 1, highest + 1 + len(new)))
    for part in parts.values():
        flown = [s.index for s in _steps_of(part)]
        assert flown == sorted(flown)
    # The two parts' reservations (the joining drone's with its wait) keep the minima.
    stored = {r.drone.drone_id: r for r in Reservation.objects.filter(ended_at__isnull=True)}
    other = reservations._reserved(stored[ALARMING])
    flight = Flight([Leg.from_list(v) for v in stored[JOINING].legs], 2.0, 15.0, 10.0)
    assert Airspace([other]).first_conflict(flight) is None
    # One wait shorter is not enough: the shortest wait was chosen.
    shorter = [
        {"command": "sleep", "params": {"value": delay - 10}},
        *[{"command": s.command, "params": s.params} for s in joining[1:]],
    ]
    drone = Drone.objects.get(drone_id=JOINING)
    sooner = reservations.planned_legs(drone, shorter)[0]
    assert Airspace([other]).first_conflict(Flight(sooner, 2.0, 15.0, 10.0)) is not None


def test_without_staggering_the_same_split_is_declined_naming_the_conflict(world, outbox, settings):
    settings.AIRSPACE_STAGGER_MAX_S = 0
    mission, assignment, alarm = _split_mission(world)
    assert _collaborate(mission, assignment, alarm) == []
    decision = mission.events.get(data__decision="collaboration_failed")
    assert "separation minima" in decision.message and f"drone {ALARMING}" in decision.message
    assert outbox.items() == []


def test_an_alarming_drone_that_has_landed_takes_off_again_for_its_part(
    world, outbox, django_capture_on_commit_callbacks
):
    mission, assignment, alarm = _split_mission(world)
    # It finished its own steps and landed before the split was planned.
    Assignment.objects.filter(pk=assignment.pk).update(status=Assignment.Status.COMPLETED)
    Drone.objects.filter(drone_id=ALARMING).update(airborne=False, alt=0.0)
    with django_capture_on_commit_callbacks(execute=True):
        parts = {p.drone.drone_id: p for p in _collaborate(mission, assignment, alarm)}
    own = parts[ALARMING]
    assert own.status == Assignment.Status.SENT
    commands = [s.command for s in _steps_of(own)]
    assert _lift(commands) == ["arm", "takeoff"]
    assert _sent_commands(outbox, ALARMING) == commands


def _sent_commands(outbox, drone_id: str) -> list[str]:  # type: ignore[no-untyped-def]
    """The commands of the last mission start queued for the drone."""
    starts = [
        m["payload"]
        for m in outbox.items()
        if m["topic"] == f"{drone_id}/mission/in" and m["payload"].get("action") == "start"
    ]
    payload = protocol.decode_mission_payload(starts[-1]["payload"])
    return [step.command for step in payload.steps]


def _stopped(mission, assignment, error=None):  # type: ignore[no-untyped-def]
    return protocol.MissionProgress(str(mission.pk), str(assignment.pk), "stopped", error=error)


def _completed(mission, assignment):  # type: ignore[no-untyped-def]
    return protocol.MissionProgress(str(mission.pk), str(assignment.pk), "completed")


def test_a_queued_part_released_after_its_drone_landed_takes_off_first(
    world, outbox, django_capture_on_commit_callbacks
):
    mission, assignment, alarm = _split_mission(world)
    parts = {p.drone.drone_id: p for p in _collaborate(mission, assignment, alarm)}
    queued = parts[ALARMING]
    assert queued.status == Assignment.Status.QUEUED
    assert "takeoff" not in [s.command for s in _steps_of(queued)]
    outbox.clear()
    # The stop came too late: the drone had landed at the end of its own steps.
    alarming = Drone.objects.get(drone_id=ALARMING)
    Drone.objects.filter(pk=alarming.pk).update(airborne=False, alt=0.0)
    with django_capture_on_commit_callbacks(execute=True):
        assert apply_progress(alarming, _completed(mission, assignment)) is None
    queued.refresh_from_db()
    assert queued.status == Assignment.Status.SENT
    steps = _steps_of(queued)
    assert [s.command for s in steps][:2] == ["arm", "takeoff"] or [s.command for s in steps][
        :3
    ] == ["sleep", "arm", "takeoff"]
    assert _sent_commands(outbox, ALARMING) == [s.command for s in steps]
    # Its reservation now starts on the ground.
    reserved = Reservation.objects.get(assignment=queued, ended_at__isnull=True)
    assert min(leg[4] for leg in reserved.legs) == 0.0
    assert mission.events.filter(data__decision="takes_off_again").exists()


def test_a_landed_drone_that_may_not_take_off_again_gets_nothing_and_the_mission_fails(
    world, outbox, django_capture_on_commit_callbacks
):
    mission, assignment, alarm = _split_mission(world)
    Drone.objects.filter(drone_id=JOINING).update(online=False)  # no joining drone
    parts = _collaborate(mission, assignment, alarm)
    assert [p.status for p in parts] == [Assignment.Status.QUEUED]
    outbox.clear()
    alarming = Drone.objects.get(drone_id=ALARMING)
    Drone.objects.filter(pk=alarming.pk).update(airborne=False, alt=0.0)
    # Meanwhile the organisation's ceiling came down below the mission's height.
    Organisation.objects.filter(pk=world.org.pk).update(envelope={"max_height": 5.0})
    with django_capture_on_commit_callbacks(execute=True):
        assert apply_progress(alarming, _completed(mission, assignment)) is None
    parts[0].refresh_from_db()
    mission.refresh_from_db()
    assert parts[0].status == Assignment.Status.STOPPED
    assert [m for m in outbox.items() if m["topic"] == f"{ALARMING}/mission/in"] == []
    assert mission.status == MissionStatus.FAILED
    failed = mission.events.get(data__decision="failed")
    assert "no drone flies them" in failed.message and "may not take off" in failed.message


def _flying(world):  # type: ignore[no-untyped-def]
    drone = online_drone(world.org, "ACME_A")
    steps = [
        {"command": "arm"},
        {"command": "takeoff", "params": {"altitude": 10}},
        {"command": "navigate", "params": dict(zip(("lat", "lon"), point_at(40, 0), strict=True))},
        {"command": "land"},
    ]
    mission = create_mission(organisation=world.org, name="m", steps=steps)
    return drone, mission, start_mission(mission, drone=drone).assignment


def test_a_step_the_drone_refuses_ends_the_mission_failed(world, outbox):
    drone, mission, assignment = _flying(world)
    failed = _progress(mission, assignment, 2, status="failed")
    assert apply_progress(drone, failed) is None
    error = protocol.step_failure(2, "navigate", "not armed")
    assert apply_progress(drone, _stopped(mission, assignment, error)) is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.FAILED
    decisions = list(mission.events.filter(kind=Event.Kind.DECISION).values_list("message"))
    assert any("step 2 (navigate) failed: not armed" in m for (m,) in decisions), decisions


def test_a_mission_stopped_on_the_drone_for_another_reason_is_left_to_its_handling(world):
    """A fail-safe's stop (its CRITICAL alarm brings a replacement) is not a failed step."""
    drone, mission, assignment = _flying(world)
    stop = _stopped(mission, assignment, "battery below 25 %: returning home")
    assert apply_progress(drone, stop) is None
    assert Mission.objects.get(pk=mission.pk).status == MissionStatus.RUNNING


def test_the_failed_step_wording_is_read_back():
    assert protocol.failed_step(protocol.step_failure(7, "navigate", "not armed")) == (
        7,
        "navigate",
        "not armed",
    )
    assert protocol.failed_step("the mission was stopped") is None
    assert protocol.failed_step(None) is None


def test_a_part_refused_while_another_flies_fails_the_mission_once_that_one_is_done(world, outbox):
    mission, assignment, alarm = _split_mission(world)
    parts = {p.drone.drone_id: p for p in _collaborate(mission, assignment, alarm)}
    joining = Drone.objects.get(drone_id=JOINING)
    refused = protocol.MissionProgress(
        str(mission.pk), str(parts[JOINING].pk), "rejected", error="no GPS fix"
    )
    assert apply_progress(joining, refused) is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING  # the alarming drone's part is to fly
    alarming = Drone.objects.get(drone_id=ALARMING)
    assert apply_progress(alarming, _stopped(mission, assignment)) is None
    own = parts[ALARMING]
    own.refresh_from_db()
    assert own.status == Assignment.Status.SENT
    _complete(alarming, mission, own, own.step_indexes)
    assert apply_progress(alarming, _completed(mission, own)) is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.FAILED
    failed = mission.events.get(data__decision="failed")
    assert f"{JOINING} rejected its steps (no GPS fix)" in failed.message, failed.message


@pytest.mark.parametrize("seed", range(6))
def test_the_jumping_search_finds_the_plain_searchs_layer_and_wait(seed):
    """`lay` picks the reserved legs near the track once and jumps from wait to wait; the
    plain definition tries every layer and every multiple of the step against the whole
    airspace. Both give the same part, on crowded airspaces where a wait is needed."""
    import random

    from bench.bench_airspace import NOW, ORIGIN, PACE, _mission
    from bench.bench_stagger import part

    rng = random.Random(seed)
    reserved = []
    for k in range(40):
        home = offset(*ORIGIN, rng.uniform(-400, 400), rng.uniform(-200, 1000))
        steps = _mission(*home, rng.choice([10.0, 24.0, 38.0]), rng.randint(3, 12), rng)
        legs, _ = flight_legs(steps, (*home, 0.0), NOW + rng.uniform(-60, 300), PACE)
        reserved.append(
            Reserved(str(k), f"D{k}", 1, [leg.to_list() for leg in legs], 2.0, 30.0, 10.0)
        )
    search = Search((*ORIGIN, 0.0), NOW, PACE, (30.0, 10.0), 10.0, 1800.0)
    layers = [10.0, 24.0, 38.0]
    fast, clash = lay(part(), layers, Airspace(reserved), search)
    plain, plain_clash = lay_plainly(part(), layers, Airspace(reserved), search)
    if plain is None:
        assert fast is None and (clash.leg, clash.reserved.key) == (
            plain_clash.leg,
            plain_clash.reserved.key,
        )
    else:
        assert fast is not None and (fast.delay_s, fast.steps) == (plain.delay_s, plain.steps)


def test_a_replacement_with_no_clear_layer_waits_for_the_failing_drones_way_down(world, outbox):
    """The failing drone comes down where it stopped; its replacement flies there at the
    mission's 10 m and no layer fits under a 20 m ceiling: it waits on the ground until
    the failing drone's descent is behind it, rather than the replacement being refused."""
    Organisation.objects.filter(pk=world.org.pk).update(envelope={"max_height": 20.0})
    failing, mission, assignment, alarm = failing_over_origin(world, -20.0)
    replacing = replace(mission, assignment, alarm)
    assert replacing is not None, list(mission.events.values_list("message", flat=True))
    steps = _steps_of(replacing)
    assert [s.command for s in steps[:3]] == ["sleep", "arm", "takeoff"]
    assert steps[2].params["altitude"] == 10.0 and steps[0].params["value"] > 0
    assert replacing.preparation[0] == steps[0].index
    # Its reservation is clear of the failing drone's way down.
    down = reservations._reserved(Reservation.objects.get(drone=failing, ended_at__isnull=True))
    mine = Reservation.objects.get(assignment=replacing, ended_at__isnull=True)
    flight = Flight([Leg.from_list(v) for v in mine.legs], 2.0, 30.0, 10.0)
    assert Airspace([down]).first_conflict(flight) is None

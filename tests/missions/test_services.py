"""Mission execution on the real database and Redis outbox, with the drone's side played by
protocol messages (the end-to-end tests fly real simulated drones)."""

from __future__ import annotations

import time

import pytest

from missions import collaboration, replacement
from missions.creation import create_mission
from missions.errors import MissionError
from missions.models import Assignment, Event, MissionStatus, Step, StepStatus
from missions.planning import coverage, mission_steps
from missions.progress import apply_progress
from missions.startstop import start_mission
from onboard import protocol

from .conftest import online_drone, point_at, rectangle


def _steps(n_waypoints: int = 3) -> list[dict]:
    points = [point_at(10.0 * i, 0.0) for i in range(n_waypoints)]
    return mission_steps(points, altitude=10)


def _progress(mission, assignment, index, status="completed", command="navigate", ts=None):  # type: ignore[no-untyped-def]
    return protocol.StepProgress(
        mission_id=str(mission.pk),
        assignment_id=str(assignment.pk),
        index=index,
        command=command,
        status=status,
        position=protocol.Position(*point_at(0, 0), 10.0),
        duration_s=1.5,
        ts=ts or time.time(),
    )


def _complete(drone, mission, assignment, indexes):  # type: ignore[no-untyped-def]
    for index in indexes:
        step = Step.objects.get(mission=mission, index=index)
        assert (
            apply_progress(drone, _progress(mission, assignment, index, "started", step.command))
            is None
        )
        assert (
            apply_progress(drone, _progress(mission, assignment, index, "completed", step.command))
            is None
        )


def test_a_step_with_an_unknown_command_is_refused_naming_the_step(world):
    steps = [{"command": "arm"}, {"command": "fly_to_the_moon", "params": {}}]
    with pytest.raises(MissionError) as refused:
        create_mission(organisation=world.org, name="x", steps=steps)
    assert refused.value.field == "steps[1].command"
    assert "unknown command" in refused.value.message


def test_a_waypoint_off_the_globe_is_refused_naming_its_latitude(world):
    steps = [{"command": "navigate", "params": {"lat": 91.0, "lon": 0.0}}]
    with pytest.raises(MissionError) as refused:
        create_mission(organisation=world.org, name="x", steps=steps)
    assert refused.value.field == "steps[0].params.lat"


def test_start_gives_every_step_to_the_nearest_available_drone(
    world, outbox, django_capture_on_commit_callbacks
):
    far = online_drone(world.org, "ACME_FAR", north=500)
    near = online_drone(world.org, "ACME_NEAR", north=20)
    online_drone(world.org, "ACME_EMPTY", north=1, battery=0.1)  # under the reserve
    mission = create_mission(organisation=world.org, name="survey", steps=_steps())
    with django_capture_on_commit_callbacks(execute=True):
        started = start_mission(mission)

    assert started.assignment.drone == near != far
    assert started.assignment.step_indexes == list(range(len(_steps())))
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING and mission.started_at is not None
    [item] = outbox.items()
    assert item["topic"] == "ACME_NEAR/mission/in"
    start = protocol.parse_mission_request(item["payload"])
    payload = protocol.decode_mission_payload(start.payload)
    assert payload.mission_id == str(mission.pk)
    assert payload.assignment_id == str(started.assignment.pk)
    assert [s.index for s in payload.steps] == list(range(len(_steps())))


def test_starting_with_no_drone_available_is_refused_and_changes_nothing(world, outbox):
    online_drone(world.org, "ACME_LOW", battery=0.2)
    mission = create_mission(organisation=world.org, name="x", steps=_steps())
    with pytest.raises(MissionError) as refused:
        start_mission(mission)
    assert refused.value.status == 409 and refused.value.field == "drone"
    mission.refresh_from_db()
    assert mission.status == MissionStatus.DRAFT
    assert not mission.assignments.exists() and outbox.items() == []


def test_the_mission_completes_when_every_step_is_completed_whoever_did_it(world, outbox):
    drone = online_drone(world.org, "ACME_A")
    mission = create_mission(organisation=world.org, name="x", steps=_steps(2))
    assignment = start_mission(mission).assignment
    indexes = assignment.step_indexes
    _complete(drone, mission, assignment, indexes[:-1])
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING
    _complete(drone, mission, assignment, indexes[-1:])
    mission.refresh_from_db()
    assert mission.status == MissionStatus.COMPLETED and mission.ended_at is not None
    step = mission.steps.get(index=2)
    assert step.drone == drone and step.duration_s == 1.5 and step.position["alt"] == 10.0


def test_a_completed_mission_report_recovers_step_reports_lost_on_the_way(world, outbox):
    drone = online_drone(world.org, "ACME_A")
    mission = create_mission(organisation=world.org, name="x", steps=_steps(2))
    assignment = start_mission(mission).assignment
    _complete(drone, mission, assignment, [0, 1])
    done = protocol.MissionProgress(str(mission.pk), str(assignment.pk), "completed")
    assert apply_progress(drone, done) is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.COMPLETED
    assert set(mission.steps.values_list("status", flat=True)) == {StepStatus.COMPLETED}


def test_progress_from_a_drone_that_was_not_given_the_mission_is_dropped(world, outbox):
    online_drone(world.org, "ACME_A")
    intruder = online_drone(world.org, "ACME_B", north=900)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(1))
    assignment = start_mission(mission).assignment
    assert apply_progress(intruder, _progress(mission, assignment, 0)) == "unknown_assignment"
    other = online_drone(world.other_org, "GLOBEX_9")
    assert apply_progress(other, _progress(mission, assignment, 0)) == "unknown_mission"
    assert mission.steps.get(index=0).status == StepStatus.PENDING


def _alarm_event(mission, drone, level="CRITICAL", north=20.0):  # type: ignore[no-untyped-def]
    lat, lon = point_at(north, 0)
    return Event.objects.create(
        mission=mission,
        drone=drone,
        kind=Event.Kind.ALARM,
        data={
            "level": level,
            "position": {"lat": lat, "lon": lon, "alt": 10.0},
            "received_at": time.time(),
        },
    )


def test_a_duplicated_critical_alarm_causes_one_replacement(world, outbox):
    first = online_drone(world.org, "ACME_A")
    second = online_drone(world.org, "ACME_B", north=50)
    online_drone(world.org, "ACME_C", north=300)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2, 3])  # arm, takeoff, first waypoint
    alarm = _alarm_event(mission, first)

    runs = [
        replacement.replace_drone(
            mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
        )
        for _ in range(2)
    ]
    assert runs[0] is not None and runs[0] == runs[1]
    assert mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT).count() == 1
    replacing = runs[0]
    assert replacing.drone == second
    assignment.refresh_from_db()
    assert assignment.status == Assignment.Status.STOPPED
    # Remaining steps keep their original indexes, after arm/takeoff/fly-to preparation.
    remaining = list(
        mission.steps.filter(index__in=assignment.step_indexes)
        .exclude(status=StepStatus.COMPLETED)
        .values_list("index", flat=True)
    )
    assert replacing.step_indexes == remaining
    prep = [mission.steps.get(index=i).command for i in replacing.preparation]
    assert prep[:4] == ["arm", "takeoff", "wait_for_flight", "navigate"]
    decision = mission.events.get(kind=Event.Kind.DECISION, data__decision="replacement")
    assert decision.data["drone_id"] == "ACME_B" and decision.data["since_alarm_ms"] >= 0


def test_replacement_with_no_drone_available_pauses_and_resumes_when_one_comes_online(
    world, outbox
):
    first = online_drone(world.org, "ACME_A")
    mission = create_mission(organisation=world.org, name="x", steps=_steps(3))
    assignment = start_mission(mission).assignment
    _complete(first, mission, assignment, [0, 1, 2])
    alarm = _alarm_event(mission, first)

    assert (
        replacement.replace_drone(
            mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
        )
        is None
    )
    mission.refresh_from_db()
    assert mission.status == MissionStatus.PAUSED
    notice = mission.events.get(data__decision="paused")
    assert notice.data["operator_notice"] is True
    assert replacement.resume_paused() == []

    online_drone(world.org, "ACME_LATE", north=100)
    assert replacement.resume_paused() == [str(mission.pk)]
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING
    assert (
        mission.assignments.get(reason=Assignment.Reason.REPLACEMENT).drone.drone_id == "ACME_LATE"
    )


def test_out_measure_extends_the_area_and_splits_it_among_three_drones(world, outbox):
    vertices = rectangle(35, 28)
    area = coverage(vertices, 7)
    assert len(area.waypoints) == 30
    steps = mission_steps(
        area.waypoints,
        altitude=10,
        intermediate_action={"command": "sleep", "params": {"value": 2}},
    )
    extensibility = {
        "vectors": area.vectors.to_dict(),
        "step_distance": 7,
        "intermediate_action": {"command": "sleep", "params": {"value": 2}},
    }
    alarming = online_drone(world.org, "ACME_A")
    online_drone(world.org, "ACME_B", north=-30)
    online_drone(world.org, "ACME_C", north=-40, east=40)
    mission = create_mission(
        organisation=world.org, name="co2", steps=steps, extensibility=extensibility
    )
    assignment = start_mission(mission, drone=alarming).assignment
    alarm = _alarm_event(mission, alarming, level="OUT_MEASURE", north=14)

    created = collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    again = collaboration.collaborate(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    assert again == [] and len(created) == 3
    decision = mission.events.get(data__decision="collaboration")
    assert decision.data["waypoints"] == 56 and decision.data["area_m2"] == pytest.approx(
        2058, abs=1
    )
    navigates = sum(
        mission.steps.filter(index__in=a.step_indexes, command="navigate").count() for a in created
    )
    assert navigates == 56
    mine = next(a for a in created if a.drone == alarming)
    assert mine.preparation == [] and mine.status == Assignment.Status.QUEUED
    assert all(
        a.preparation and a.status == Assignment.Status.SENT for a in created if a is not mine
    )
    assert not mission.steps.filter(
        index__in=assignment.step_indexes, status=StepStatus.PENDING
    ).exists()

    # The alarming drone gets its part once it reports the old assignment stopped.
    stopped = protocol.MissionProgress(str(mission.pk), str(assignment.pk), "stopped")
    outbox.clear()
    apply_progress(alarming, stopped)
    mine.refresh_from_db()
    assert mine.status == Assignment.Status.SENT


def test_the_virtual_alarm_step_is_not_handed_over_though_its_report_comes_after_the_alarm(
    world, outbox
):
    first = online_drone(world.org, "ACME_A")
    online_drone(world.org, "ACME_B", north=50)
    steps = [{"command": s["command"], "params": s["params"]} for s in _steps(3)]
    steps.insert(4, {"command": "virtualalarm", "params": {"level": "CRITICAL", "message": "test"}})
    mission = create_mission(organisation=world.org, name="x", steps=steps)
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2, 3])
    apply_progress(first, _progress(mission, assignment, 4, "started", "virtualalarm"))
    alarm = _alarm_event(mission, first)
    alarm.data["index"] = 4
    alarm.save()

    replacing = replacement.replace_drone(
        mission_id=str(mission.pk), assignment_id=str(assignment.pk), alarm_event_id=alarm.pk
    )
    assert 4 not in replacing.step_indexes and replacing.step_indexes[0] == 5
    # The late report from the stopped drone still counts.
    apply_progress(first, _progress(mission, assignment, 4, "completed", "virtualalarm"))
    step = mission.steps.get(index=4)
    assert step.status == StepStatus.COMPLETED and step.drone == first


def test_a_drone_the_mission_already_replaced_is_not_brought_back(world, outbox):
    first = online_drone(world.org, "ACME_A")
    second = online_drone(world.org, "ACME_B", north=50)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2])
    replacing = replacement.replace_drone(
        mission_id=str(mission.pk),
        assignment_id=str(assignment.pk),
        alarm_event_id=_alarm_event(mission, first).pk,
    )
    assert replacing.drone == second
    # Now the replacement fails too: the first drone (still online) is not chosen again.
    again = replacement.replace_drone(
        mission_id=str(mission.pk),
        assignment_id=str(replacing.pk),
        alarm_event_id=_alarm_event(mission, second).pk,
    )
    assert again is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.PAUSED


def test_a_replacement_rerun_after_a_worker_died_before_sending_sends_it_once(
    world, outbox, django_capture_on_commit_callbacks
):
    first = online_drone(world.org, "ACME_A")
    online_drone(world.org, "ACME_B", north=50)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2])
    alarm = _alarm_event(mission, first)
    kwargs = {
        "mission_id": str(mission.pk),
        "assignment_id": str(assignment.pk),
        "alarm_event_id": alarm.pk,
    }
    # The first run commits but its worker dies before the after-commit send.
    replacing = replacement.replace_drone(**kwargs)
    assert outbox.items() == []

    with django_capture_on_commit_callbacks(execute=True):
        assert replacement.replace_drone(**kwargs) == replacing
    with django_capture_on_commit_callbacks(execute=True):
        assert replacement.replace_drone(**kwargs) == replacing
    starts = [i for i in outbox.items() if i["payload"].get("action") == "start"]
    assert [s["topic"] for s in starts] == ["ACME_B/mission/in"]
    assert starts[0]["payload"]["assignment_id"] == str(replacing.pk)


def _listen(mission):  # type: ignore[no-untyped-def]
    """A channel in the mission's live group, on the real channel layer; `drain()` reads it."""
    from asgiref.sync import async_to_sync
    from channels.layers import get_channel_layer

    from missions import live

    layer = get_channel_layer()
    channel = async_to_sync(layer.new_channel)()
    async_to_sync(layer.group_add)(live.group_name(mission.pk), channel)

    async def drain() -> list[dict]:
        import asyncio

        received = []
        while True:
            try:
                message = await asyncio.wait_for(layer.receive(channel), 1.0)
            except TimeoutError:
                return received
            received.append(message["payload"])

    return async_to_sync(drain)


def test_a_redelivered_completion_pushes_the_accepted_event_again_when_the_first_push_died(
    world, outbox, django_capture_on_commit_callbacks
):
    """The process that took the last step's report committed it and died before pushing
    it: the page's copy comes from the redelivery, with the accepted event's id."""
    drone = online_drone(world.org, "ACME_A")
    mission = create_mission(organisation=world.org, name="x", steps=_steps(2))
    assignment = start_mission(mission).assignment
    *first, last = assignment.step_indexes
    _complete(drone, mission, assignment, first)
    report = _progress(
        mission, assignment, last, "completed", mission.steps.get(index=last).command
    )
    with django_capture_on_commit_callbacks(execute=False):
        assert apply_progress(drone, report) is None  # committed; its pushes never ran
    drain = _listen(mission)
    with django_capture_on_commit_callbacks(execute=True):
        assert apply_progress(drone, report) is None
    pushed = drain()
    accepted = mission.events.get(
        kind=Event.Kind.STEP, data__index=last, data__status="completed", data__ignored=False
    )
    replays = [p for p in pushed if p.get("id") == accepted.pk]
    assert len(replays) == 1 and replays[0]["data"]["ignored"] is False, pushed
    assert {"type": "mission", "status": "completed"} in pushed, pushed
    # Still one accepted completion, and the copy (the same message) is not recorded again.
    copies = mission.events.filter(kind=Event.Kind.STEP, data__index=last, data__status="completed")
    assert [e.data["ignored"] for e in copies] == [False]


def test_an_alarm_task_waits_for_its_alarm_and_a_rolled_back_alarm_decides_nothing(world, outbox):
    """The alarm's task is queued inside the alarm's transaction (a gateway killed after
    the commit must not leave the alarm undecided): with no alarm on record it waits,
    then gives up; with the alarm committed it replaces the drone."""
    from missions import tasks

    first = online_drone(world.org, "ACME_A")
    online_drone(world.org, "ACME_B", north=50)
    mission = create_mission(organisation=world.org, name="x", steps=_steps(4))
    assignment = start_mission(mission, drone=first).assignment
    _complete(first, mission, assignment, [0, 1, 2, 3])
    ids = {"mission_id": str(mission.pk), "assignment_id": str(assignment.pk)}
    tasks.replace_drone.apply(kwargs={**ids, "alarm_event_id": 2**31 - 1})
    assert not mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT).exists()
    assignment.refresh_from_db()
    assert assignment.status in Assignment.ACTIVE
    alarm = _alarm_event(mission, first)
    tasks.replace_drone.apply(kwargs={**ids, "alarm_event_id": alarm.pk})
    assert mission.assignments.filter(reason=Assignment.Reason.REPLACEMENT).count() == 1

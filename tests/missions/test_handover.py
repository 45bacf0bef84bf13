from __future__ import annotations

from collections import Counter

import pytest

from missions.handover import plan_collaboration, plan_replacement
from missions.planning import PlanningError, coverage, extend, mission_steps
from tests.missions.planning import point_at, rectangle


def with_status(steps, completed_through):
    """The mission as the ground tracks it: steps up to an index completed, the rest pending."""
    return [
        {**s, "status": "completed" if s["index"] <= completed_through else "pending"}
        for s in steps
    ]


@pytest.fixture
def self_replacement_steps():
    waypoints = coverage(rectangle(32, 64), 10).waypoints
    assert len(waypoints) == 28
    return waypoints, mission_steps(waypoints, altitude=10)


def test_replacement_after_13_waypoints_hands_over_the_other_15_and_each_index_once(
    self_replacement_steps,
):
    waypoints, steps = self_replacement_steps
    # arm, takeoff, then (navigate, wait) per waypoint: 13 waypoints end at index 27.
    tracked = with_status(steps, completed_through=27)
    stop = tuple(waypoints[12])
    plan = plan_replacement(tracked, stop_position=stop, altitude=10, drone_id="DRONE2")
    (assignment,) = plan.assignments
    assert assignment.drone_id == "DRONE2"
    # Climb, then go: it reaches its height over its own column before it leaves.
    assert [s["command"] for s in assignment.steps[:5]] == [
        "arm",
        "takeoff",
        "wait_for_flight",
        "navigate",
        "wait_for_flight",
    ]
    assert assignment.steps[1]["params"] == {"altitude": 10.0}
    assert assignment.steps[3]["params"] == {"lat": stop[0], "lon": stop[1]}
    assert assignment.preparation_indexes == [59, 60, 61, 62, 63]
    assert plan.new_steps == assignment.steps[:5]

    first_drone = [s["index"] for s in tracked if s["status"] == "completed"]
    second_drone = assignment.handed_over_indexes
    done = Counter(first_drone + second_drone)
    assert sorted(done) == list(range(59)), "no step skipped"
    assert set(done.values()) == {1}, "no step done twice"
    navigated = [s for s in assignment.steps[5:] if s["command"] == "navigate"]
    assert len(navigated) == 15
    assert navigated[0]["params"] == steps[28]["params"]
    assert assignment.steps[-1] == {"index": 58, "command": "land", "params": {}}


def test_replacement_steps_keep_their_original_indexes_and_content(self_replacement_steps):
    _, steps = self_replacement_steps
    plan = plan_replacement(with_status(steps, 41), stop_position=(40.63, -8.65), altitude=10)
    assignment = plan.assignments[0]
    handed = assignment.steps[len(assignment.preparation_indexes) :]
    assert handed == [s for s in steps if s["index"] > 41]


def test_replacement_mid_waypoint_first_flies_to_the_waypoint_its_wait_is_for(
    self_replacement_steps,
):
    waypoints, steps = self_replacement_steps
    # The failing drone was sent to waypoint 14 (index 28) but had not arrived.
    plan = plan_replacement(with_status(steps, 28), stop_position=point_at(5, 5), altitude=10)
    assignment = plan.assignments[0]
    assert [s["command"] for s in assignment.steps[:7]] == [
        "arm",
        "takeoff",
        "wait_for_flight",
        "navigate",
        "wait_for_flight",
        "navigate",
        "wait_for_flight",
    ]
    assert assignment.steps[5]["params"] == {"lat": waypoints[13][0], "lon": waypoints[13][1]}
    assert assignment.steps[6]["index"] == 29  # the mission's own pending wait
    assert assignment.preparation_indexes == [59, 60, 61, 62, 63, 64]


def test_replacement_without_a_gps_fix_goes_to_the_last_completed_waypoint(
    self_replacement_steps,
):
    waypoints, steps = self_replacement_steps
    plan = plan_replacement(with_status(steps, 27), stop_position=None, altitude=10)
    assert plan.assignments[0].steps[3]["params"] == {
        "lat": waypoints[12][0],
        "lon": waypoints[12][1],
    }


def test_replacement_before_anything_ran_sends_the_whole_mission_without_preparation(
    self_replacement_steps,
):
    _, steps = self_replacement_steps
    plan = plan_replacement(with_status(steps, -1), stop_position=None, altitude=10)
    assert plan.assignments[0].steps == steps
    assert plan.new_steps == []


def test_replacement_of_a_finished_mission_is_refused(self_replacement_steps):
    _, steps = self_replacement_steps
    with pytest.raises(PlanningError, match="nothing to hand over"):
        plan_replacement(with_status(steps, 58), stop_position=None, altitude=10)


def test_replacement_refuses_repeated_indexes():
    steps = [
        {"index": 0, "command": "arm", "params": {}, "status": "completed"},
        {"index": 0, "command": "land", "params": {}, "status": "pending"},
    ]
    with pytest.raises(PlanningError, match="appears twice"):
        plan_replacement(steps, stop_position=None, altitude=10)


def test_collaboration_gives_the_alarming_drone_a_part_without_preparation():
    waypoints = coverage(rectangle(35, 28), 7).waypoints
    steps = mission_steps(
        waypoints, altitude=10, intermediate_action={"command": "sleep", "params": {"value": 2}}
    )
    tracked = with_status(steps, 1 + 15 * 3)  # waypoint 15 done (navigate, wait, sleep each)
    alarm = tuple(waypoints[14])
    positions = [alarm, point_at(-60, 0), point_at(80, 80)]
    extension = extend(
        rectangle(35, 28), 7, center=alarm, joining_drones=2, drone_positions=positions
    )
    plan = plan_collaboration(
        tracked,
        extension=extension,
        drone_ids=["A", "B", "C"],
        alarming_drone="A",
        altitude=10,
        intermediate_action={"command": "sleep", "params": {"value": 2}},
    )
    by_drone = {a.drone_id: a for a in plan.assignments}
    assert set(by_drone) == {"A", "B", "C"}
    assert by_drone["A"].preparation_indexes == []
    assert by_drone["A"].steps[0]["command"] == "navigate"
    for joining in ("B", "C"):
        commands = [s["command"] for s in by_drone[joining].steps[:4]]
        # It climbs to its height before it leaves (no slant across lower layers).
        assert commands == ["arm", "takeoff", "wait_for_flight", "navigate"]
        assert len(by_drone[joining].preparation_indexes) == 3
    covered = sorted(i for a in plan.assignments for i in a.waypoint_indexes)
    assert covered == list(range(56))
    navigated = [s for a in plan.assignments for s in a.steps if s["command"] == "navigate"]
    assert len(navigated) == 56
    new_indexes = [s["index"] for s in plan.new_steps]
    assert new_indexes == list(range(len(steps), len(steps) + len(new_indexes)))
    assert plan.superseded_indexes == [s["index"] for s in tracked if s["status"] != "completed"]


def test_collaboration_needs_parts_assigned_to_drones():
    steps = mission_steps([[40.0, -8.0]], altitude=10)
    extension = extend(rectangle(35, 28), 7, center=point_at(0, 0), joining_drones=1)
    with pytest.raises(PlanningError) as caught:
        plan_collaboration(
            with_status(steps, 2),
            extension=extension,
            drone_ids=["A", "B"],
            alarming_drone="A",
            altitude=10,
        )
    assert caught.value.field == "extension"

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from missions.planning import coverage, mission_steps
from missions.qgc_plan import (
    MAX_PLAN_BYTES,
    QgcPlanError,
    dumps,
    export_plan,
    export_qgc_plan,
    import_plan,
)
from onboard.protocol import encode_mission_payload
from terrain.guard import mission_climbs
from tests.missions.planning import rectangle

FIXTURES = Path(__file__).parent / "fixtures"
PLANS = ["survey_photos_rtl.plan", "loiter_digicam_land.plan"]


def load(name):
    return json.loads((FIXTURES / name).read_text())


@pytest.mark.parametrize("name", PLANS)
def test_a_qgroundcontrol_plan_imports_and_reexports_with_equal_items_fence_and_rally(name):
    original = load(name)
    plan = import_plan((FIXTURES / name).read_text())
    exported = json.loads(dumps(export_qgc_plan(plan)))
    assert exported["mission"]["items"] == original["mission"]["items"]
    assert exported["geoFence"] == original["geoFence"]
    assert exported["rallyPoints"] == original["rallyPoints"]
    for key in ("plannedHomePosition", "cruiseSpeed", "hoverSpeed", "firmwareType", "vehicleType"):
        assert exported["mission"][key] == original["mission"][key]
    assert exported["fileType"] == "Plan" and exported["version"] == 1


@pytest.mark.parametrize("name", PLANS)
def test_an_imported_plan_is_a_mission_a_drone_accepts(name):
    plan = import_plan((FIXTURES / name).read_text())
    assert encode_mission_payload("m1", "a1", plan.steps)


def test_survey_plan_becomes_arm_takeoff_waypoints_pictures_and_return_home():
    plan = import_plan(load("survey_photos_rtl.plan"))
    commands = [s["command"] for s in plan.steps]
    # The autopilot completes the take-off item before the next: a wait for its height.
    assert commands[:3] == ["arm", "takeoff", "wait_for_flight"]
    assert plan.steps[1]["params"]["altitude"] == 10
    assert commands.count("takepic") == 3
    assert commands[-3:] == ["navigate", "wait_for_flight", "land"]
    home = plan.steps[-3]["params"]
    assert (home["lat"], home["lon"]) == (40.6303, -8.6575)
    # A 2 s hold is a sleep after arrival; a 1.5 m acceptance radius is the wait's tolerance.
    assert {"index": 8, "command": "sleep", "params": {"value": 2}} in plan.steps
    assert plan.steps[11]["params"] == {"horizontal_tolerance": 1.5}
    assert plan.steps[10]["params"]["altitude_delta"] == pytest.approx(7.214466517236122)


def test_geofence_and_rally_points_come_back_as_plain_values():
    plan = import_plan(load("survey_photos_rtl.plan"))
    assert plan.geofence["circles"] == [
        {"inclusion": True, "center": [40.63052, -8.65722], "radius": 150.5}
    ]
    assert [p["inclusion"] for p in plan.geofence["polygons"]] == [True, False]
    assert plan.geofence["polygons"][1]["polygon"][0] == [40.63045, -8.65705]
    assert plan.rally_points == [[40.6299, -8.6571, 30], [40.6308, -8.6579, 25]]
    json.dumps(plan.to_dict())  # storable as it is


def test_an_unknown_command_is_refused_naming_the_item():
    plan = load("survey_photos_rtl.plan")
    plan["mission"]["items"][3]["command"] = 177
    with pytest.raises(QgcPlanError) as caught:
        import_plan(plan)
    assert caught.value.field == "mission.items[3]"
    assert "item 4 (MAV_CMD_DO_JUMP, command 177" in caught.value.message
    assert "doJumpId 4" in caught.value.message


def test_a_complex_item_without_generated_items_is_refused_with_a_way_out():
    plan = load("survey_photos_rtl.plan")
    plan["mission"]["items"][1] = {"type": "ComplexItem", "complexItemType": "StructureScan"}
    with pytest.raises(QgcPlanError, match="no generated items") as caught:
        import_plan(plan)
    assert caught.value.field == "mission.items[1]"


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda p: p.update(fileType="Mission"), "fileType"),
        (lambda p: p["mission"].update(version=1), "mission.version"),
        (lambda p: p["mission"]["items"][1]["params"].pop(), "mission.items[1].params"),
        (lambda p: p["mission"]["items"][1]["params"].__setitem__(4, 123.0), "mission.items[1]"),
        (lambda p: p["mission"]["items"][1].update(frame=10), "mission.items[1]"),  # no terrain
        (lambda p: p["mission"]["items"][3]["params"].__setitem__(0, 1e9), "mission.items[3]"),
        (lambda p: p["mission"].update(items=[]), "mission.items"),
        (lambda p: p["rallyPoints"]["points"].append([1, 2]), "rallyPoints.points[2]"),
        (
            lambda p: p["geoFence"]["polygons"][0]["polygon"].__setitem__(0, [40.6]),
            "geoFence.polygons[0].polygon[0]",
        ),
        (
            lambda p: p["geoFence"]["circles"][0]["circle"].update(radius=-1),
            "geoFence.circles[0].circle.radius",
        ),
    ],
)
def test_malformed_plans_are_refused_naming_the_field(mutate, field):
    plan = copy.deepcopy(load("survey_photos_rtl.plan"))
    mutate(plan)
    with pytest.raises(QgcPlanError) as caught:
        import_plan(plan)
    assert caught.value.field == field


def test_text_that_is_not_json_is_refused():
    with pytest.raises(QgcPlanError) as caught:
        import_plan("{not json")
    assert caught.value.field == "file"


def test_our_coverage_mission_exports_as_takeoff_waypoints_photos_and_land():
    waypoints = coverage(rectangle(32, 64), 8).waypoints
    steps = mission_steps(waypoints, altitude=12, intermediate_action="takepic")
    document = export_plan(steps, home=[40.6303, -8.6575, 8.0])
    items = document["mission"]["items"]
    assert [i["command"] for i in items[:3]] == [22, 16, 2000]
    assert items[0]["params"][6] == 12
    assert items[1]["params"][4:] == [waypoints[0][0], waypoints[0][1], 12]
    assert items[1]["params"][1] == 2.0  # the wait's tolerance as acceptance radius
    assert [i["command"] for i in items].count(16) == 45
    assert items[-1]["command"] == 21
    assert [i["doJumpId"] for i in items] == list(range(1, len(items) + 1))
    again = import_plan(dumps(document))
    # Read back, the take-off item waits for its height as the autopilot flies it.
    commands = [s["command"] for s in steps]
    assert [s["command"] for s in again.steps] == [*commands[:2], "wait_for_flight", *commands[2:]]


def test_steps_without_a_qgroundcontrol_item_are_refused_on_export_naming_the_step():
    steps = mission_steps(
        [[40.0, -8.0]],
        altitude=10,
        intermediate_action={"command": "sense", "params": {"sensor": "CO2"}},
    )
    with pytest.raises(QgcPlanError) as caught:
        export_plan(steps)
    assert caught.value.field == "steps[4] (index 4)"


def test_a_hover_and_capture_survey_flies_the_items_qgroundcontrol_generated():
    plan = import_plan((FIXTURES / "hover_survey.plan").read_text())
    commands = [s["command"] for s in plan.steps]
    assert commands[:3] == ["arm", "takeoff", "wait_for_flight"]
    assert commands[3:15] == ["navigate", "wait_for_flight", "takepic"] * 4
    assert commands[-3:] == ["navigate", "wait_for_flight", "land"]
    survey = load("hover_survey.plan")["mission"]["items"][1]["TransectStyleComplexItem"]["Items"]
    exported = export_qgc_plan(plan)["mission"]["items"]
    # Re-exported as the simple items the survey stood for, renumbered after the takeoff.
    for ours, theirs in zip(exported[1:9], survey, strict=True):
        assert ours["command"] == theirs["command"]
        assert ours["params"] == theirs["params"]
        assert ours["doJumpId"] == theirs["doJumpId"]


def test_a_survey_triggering_the_camera_by_distance_takes_pictures_while_flying():
    plan = load("hover_survey.plan")
    inner = plan["mission"]["items"][1]["TransectStyleComplexItem"]["Items"]
    inner[1] = {
        "autoContinue": True,
        "command": 206,
        "doJumpId": 3,
        "frame": 2,
        "params": [25, 0, 1, 0, 0, 0, 0],
        "type": "SimpleItem",
    }
    steps = import_plan(plan).steps
    waits = [s["params"] for s in steps if s["command"] == "wait_for_flight"]
    assert waits[:2] == [{}, {}] and waits[2]["photo_distance"] == 25


def test_a_complex_item_nested_in_a_survey_is_refused_before_it_is_read():
    plan = load("hover_survey.plan")
    survey = plan["mission"]["items"][1]
    nested = copy.deepcopy(survey)
    for _ in range(400):  # deep enough to exhaust the reader's stack were it followed
        nested = {**copy.deepcopy(survey), "TransectStyleComplexItem": {"Items": [nested]}}
    plan["mission"]["items"][1] = nested
    with pytest.raises(QgcPlanError, match="complex item inside a complex item"):
        import_plan(plan)


def test_a_plan_over_the_size_limit_is_refused_before_it_is_parsed():
    with pytest.raises(QgcPlanError, match="is over"):
        import_plan(b" " * (MAX_PLAN_BYTES + 1))


@pytest.mark.parametrize("name", [*PLANS, "hover_survey.plan"])
def test_an_imported_plan_flies_its_first_leg_level_after_the_climb(name):
    """The autopilot completes a take-off item before the next one: no leg of an
    imported plan is flown while its take-off is still climbing."""
    plan = import_plan((FIXTURES / name).read_text())
    takeoff = next(i for i, s in enumerate(plan.steps) if s["command"] == "takeoff")
    assert plan.steps[takeoff + 1]["command"] == "wait_for_flight"
    assert mission_climbs(plan.home, plan.steps, (0.0, 0.0, 0.0)) == {}
    # Without the wait its first leg would be checked, and flown, on a slant.
    slanted = plan.steps[: takeoff + 1] + plan.steps[takeoff + 2 :]
    assert mission_climbs(plan.home, slanted, (0.0, 0.0, 0.0))

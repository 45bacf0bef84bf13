"""Plans QGroundControl itself saved (its repository's test plans, tests/data/README.md)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missions.qgc_plan import QgcPlanError, dumps, export_qgc_plan, import_plan
from onboard.protocol import encode_mission_payload
from tests.missions.qgc_format import plan_errors

PLANS = Path(__file__).parents[1] / "data" / "qgc" / "qgroundcontrol"


def flat(lat: float, lon: float) -> float:
    """Terrain as flat as QGroundControl's plans assume home's ground to be."""
    return 488.0


def load(name: str) -> dict:
    return json.loads((PLANS / name).read_text())


def copter_plan(firmware: int) -> dict:
    """QGroundControl's ArduCopter test plan; its spline waypoint (which we do not fly) made a
    plain one, so that the whole plan reads."""
    plan = load("PX4SITL-ArduCopter.plan")
    for item in plan["mission"]["items"]:
        if item.get("command") == 82:
            item["command"] = 16
    plan["mission"]["firmwareType"] = firmware
    return plan


def rois(steps: list[dict]) -> list:
    return [s["params"].get("roi") for s in steps if s["command"] == "navigate"]


def test_an_ardupilot_region_of_interest_is_its_location_though_param_1_is_0():
    steps = import_plan(copter_plan(firmware=3), terrain=flat).steps
    # QGroundControl wrote DO_SET_ROI with param 1 = 0 after the second waypoint: ArduPilot
    # looks at the location, so every leg after it points the camera there.
    assert rois(steps)[:2] == [None, None]
    assert set(map(tuple, rois(steps)[2:])) == {(47.3700507, 8.585312)}


def test_the_same_item_for_px4_is_mavlinks_roi_none():
    legs = rois(import_plan(copter_plan(firmware=12), terrain=flat).steps)
    assert legs == [None] * len(legs)


def test_a_plan_without_a_takeoff_climbs_to_its_first_altitude_first():
    plan = load("PX4SITL-PX4-MultiRotor.plan")
    del plan["mission"]["items"][0]  # its takeoff
    steps = import_plan(plan, terrain=flat).steps
    assert [s["command"] for s in steps[:4]] == ["arm", "takeoff", "wait_for_flight", "navigate"]
    assert steps[1]["params"]["altitude"] == 60
    assert "altitude_delta" not in steps[3]["params"]
    assert encode_mission_payload("m1", "a1", steps)
    # The climb is the plan's own first altitude, so it exports as no item of its own.
    exported = json.loads(dumps(export_qgc_plan(import_plan(plan, terrain=flat))))
    assert plan_errors(exported) == []
    first = exported["mission"]["items"][0]
    assert (first["command"], first["params"][6]) == (16, 60)
    assert 22 not in [item["command"] for item in exported["mission"]["items"]]
    assert import_plan(exported, terrain=flat).steps == steps


def test_a_submarines_plan_is_refused_at_its_first_depth():
    with pytest.raises(QgcPlanError) as refused:
        import_plan((PLANS / "PX4SITL-ArduSub.plan").read_text())
    assert str(refused.value).startswith("mission.items[0].params[6]")
    assert "-5 m above home" in str(refused.value)


def test_a_climb_speed_is_refused_not_flown_as_a_horizontal_one():
    plan = load("PX4SITL-PX4-MultiRotor.plan")
    speed = next(i for i, item in enumerate(plan["mission"]["items"]) if item["command"] == 178)
    plan["mission"]["items"][speed]["params"][0] = 2
    with pytest.raises(QgcPlanError) as refused:
        import_plan(plan, terrain=flat)
    assert str(refused.value).startswith(f"mission.items[{speed}].params[0]")

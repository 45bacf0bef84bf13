"""QGC WPL 110 text missions (`.waypoints`), as ArduPilot's Mission Planner saves them and
QGroundControl reads and writes them [MAVLink file formats]."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from rest_framework.test import APIClient

from missions.qgc_plan import QgcPlanError, import_plan
from missions.wpl import plan_document, plan_from_wpl

from .conftest import point_at

PLANS = Path(__file__).parents[1] / "data" / "qgc" / "qgroundcontrol"


def wpl(home: tuple[float, float, float], *items: tuple) -> str:
    """Item 0 is home (absolute altitude), then (frame, command, p1-p4, lat, lon, alt)."""
    lines = ["QGC WPL 110", "\t".join(map(str, (0, 1, 0, 16, 0, 0, 0, 0, *home, 1)))]
    for i, (frame, command, *params) in enumerate(items, start=1):
        lines.append("\t".join(map(str, (i, 0, frame, command, *params, 1))))
    return "\r\n".join(lines) + "\r\n"


def mission_planner_file() -> str:
    lat, lon = point_at(0, 0)
    north_lat, north_lon = point_at(100, 0)
    east_lat, east_lon = point_at(100, 80)
    return wpl(
        (lat, lon, 584.09),
        (3, 22, 0, 0, 0, 0, 0, 0, 20),
        (3, 16, 0, 0, 0, 0, north_lat, north_lon, 30),
        (0, 178, 1, 5, -1, 0, 0, 0, 0),
        (3, 16, 2, 0, 0, 0, east_lat, east_lon, 30),
        (3, 20, 0, 0, 0, 0, 0, 0, 0),
    )


def test_a_mission_planner_file_becomes_the_steps_its_plan_would():
    document = plan_from_wpl(mission_planner_file())
    assert document["mission"]["plannedHomePosition"] == [*point_at(0, 0), 584.09]
    steps = import_plan(document).steps
    commands = [s["command"] for s in steps]
    assert commands[:4] == ["arm", "takeoff", "wait_for_flight", "navigate"]
    assert steps[1]["params"]["altitude"] == 20
    assert steps[3]["params"]["altitude_delta"] == 10
    second = [s for s in steps if s["command"] == "navigate"][1]
    assert second["params"]["speed"] == 5 and "altitude_delta" not in second["params"]
    assert {"command": "sleep", "params": {"value": 2.0}} in [
        {k: s[k] for k in ("command", "params")} for s in steps
    ]
    assert commands[-3:] == ["navigate", "wait_for_flight", "land"]  # return to launch


def test_qgroundcontrols_plan_and_the_same_items_as_wpl_give_the_same_steps():
    plan = json.loads((PLANS / "PX4SITL-ArduSub.plan").read_text())
    plan["mission"]["items"][0]["params"][6] = 5  # a first altitude a drone can climb to
    home = plan["mission"]["plannedHomePosition"]
    rows = [(i["frame"], i["command"], *i["params"]) for i in plan["mission"]["items"]]
    text = wpl(tuple(home), *[(f, c, *(0 if p is None else p for p in ps)) for f, c, *ps in rows])
    # The same flight; only the hints kept for re-export differ (a WPL file writes 0 where
    # the .plan wrote null for "unchanged").
    assert flown(import_plan(plan_document(text)).steps) == flown(import_plan(plan).steps)


def flown(steps: list[dict]) -> list[tuple]:
    return [(s["command"], {k: v for k, v in s["params"].items() if k != "qgc"}) for s in steps]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("QGC WPL 100\n", "line 1: expected 'QGC WPL 110'"),
        (
            "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\t1\n",
            r"needs item 0 \(home\) and at least",
        ),
        (
            "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\t1\n1\t0\t3\t16\t0\t0\n",
            "line 3: 6 columns",
        ),
        (
            "QGC WPL 110\n0 1 0 16 0 0 0 0 1 2 3 1\n2 0 3 16 0 0 0 0 1 2 3 1\n",
            "line 3: item 2 where 1",
        ),
        ("QGC WPL 110\n0 1 0 16 0 0 0 0 1 2 3 1\n1 0 3 16 0 0 0 0 nan 2 3 1\n", "not a finite"),
        ("QGC WPL 110\n0 1 0 16 0 0 0 0 1 2 3 1\n1 0 3 16.5 0 0 0 0 1 2 3 1\n", "column 4 must be"),
    ],
)
def test_a_broken_wpl_file_is_refused_naming_its_line(text, words):
    with pytest.raises(QgcPlanError, match=words):
        plan_document(text.encode())


def test_the_api_imports_a_waypoints_file_as_it_does_a_plan(world):
    client = APIClient()
    client.force_authenticate(world.operator)
    upload = io.BytesIO(b"\xef\xbb\xbf" + mission_planner_file().encode())
    upload.name = "survey.waypoints"
    response = client.post("/api/v1/missions/import-plan/", {"file": upload}, format="multipart")
    assert response.status_code == 201, response.json()
    assert [s["command"] for s in response.json()["steps"]][:2] == ["arm", "takeoff"]
    upload = io.BytesIO(b"QGC WPL 110\n0 1 0 16\n")
    upload.name = "cut.waypoints"
    refused = client.post("/api/v1/missions/import-plan/", {"file": upload}, format="multipart")
    assert refused.status_code == 400 and "line 2: 4 columns" in refused.json()["error"]

"""A QGroundControl `.plan` reaches a MAVLink vehicle intact: imported by the Mission
Planner's reader, turned into native mission items, uploaded to the simulator over the
mission protocol and read back item for item; then exported again as a `.plan`."""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim import start_simulator
from missions import qgc_plan
from onboard import protocol
from onboard.fc.mavlink import MavlinkFlightController
from onboard.mavlink_mission import MissionUploader, native_runs, plan_native_run

from .conftest import TIME_SCALE

FIXTURES = Path(__file__).resolve().parents[2] / "missions" / "fixtures"


def mission_items(steps: list[protocol.Step], home: tuple[float, float, float]):  # type: ignore[no-untyped-def]
    items, start = [], (0.0, 0.0, 0.0)
    for native, run in native_runs(steps):
        if native:
            plan = plan_native_run(run, start, home)
            items += plan.items
            start = plan.end
    return items


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
@pytest.mark.parametrize("name", ["hover_survey", "loiter_digicam_land", "survey_photos_rtl"])
def test_a_qgroundcontrol_plan_is_uploaded_to_a_mavlink_vehicle_and_read_back(
    name, autopilot, tmp_path
):
    plan = qgc_plan.import_plan((FIXTURES / f"{name}.plan").read_text())
    steps = [
        protocol.Step(
            i, s["command"], protocol.validate_command(s["command"], s["params"], mission=True)
        )
        for i, s in enumerate(plan.steps)
    ]
    home = tuple(plan.home)
    items = mission_items(steps, home)
    navigates = [s for s in steps if s.command == "navigate"]
    waypoints = [i for i in items if i.command == mavlink.MAV_CMD_NAV_WAYPOINT]
    assert len(waypoints) == len(navigates)
    for step, item in zip(navigates, waypoints, strict=True):
        assert abs(item.x - step.params["lat"] * 1e7) <= 1
        assert abs(item.y - step.params["lon"] * 1e7) <= 1
    takeoff = next(s for s in steps if s.command == "takeoff")
    assert items[0].command == mavlink.MAV_CMD_NAV_TAKEOFF
    assert items[0].z == takeoff.params["altitude"]
    assert items[-1].command == mavlink.MAV_CMD_NAV_LAND

    sim = start_simulator(
        home=home,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--autopilot", autopilot],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    try:
        fc.start()
        assert fc.wait_connected(5)
        uploader = MissionUploader(fc)
        uploader.upload(items)
        assert uploader.download() == items
    finally:
        fc.stop()
        sim.stop()

    again = qgc_plan.import_plan(qgc_plan.dumps(qgc_plan.export_qgc_plan(plan)))
    assert [s["command"] for s in again.steps] == [s["command"] for s in plan.steps]
    assert again.home == plan.home

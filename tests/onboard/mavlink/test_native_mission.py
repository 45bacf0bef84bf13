"""Native MAVLink missions: the mission protocol against the simulator, and the Mission
Worker flying a run of steps in AUTO with progress from MISSION_ITEM_REACHED."""

from __future__ import annotations

import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim import start_simulator
from onboard import protocol
from onboard.controller import Controller
from onboard.fc.mavlink import MavlinkFlightController
from onboard.mavlink_mission import (
    MissionItem,
    MissionUploader,
    MissionUploadError,
    NativeMissionWorker,
    native_runs,
    plan_native_run,
)
from onboard.navigation import NavigationProcessor, lla_to_ned

from .conftest import HOME, TIME_SCALE, wait_for


def steps(*commands: tuple[str, dict]) -> list[protocol.Step]:
    return [protocol.Step(i, c, p) for i, (c, p) in enumerate(commands)]


def test_flying_steps_become_one_native_run_and_the_rest_stay_with_the_agent():
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("changeN", {"value": 20.0}),
        ("wait_for_flight", {}),
        ("takepic", {}),
        ("changeE", {"value": 5.0}),
        ("sleep", {"value": 3.0}),
        ("land", {}),
        ("disarm", {}),
    )
    runs = [(native, [s.command for s in run]) for native, run in native_runs(mission)]
    assert runs == [
        (False, ["arm"]),
        (True, ["takeoff", "changeN", "wait_for_flight"]),
        (False, ["takepic"]),
        (True, ["changeE", "sleep", "land"]),
        (False, ["disarm"]),
    ]


def test_a_native_plan_draws_the_same_shape_as_step_by_step_control():
    home = HOME
    run = steps(
        ("takeoff", {"altitude": 10.0}),
        ("changeN", {"value": 20.0}),
        ("wait_for_flight", {}),
        ("altitude", {"value": 5.0}),
        ("navigate", {"lat": 40.631, "lon": -8.657, "altitude_delta": -3.0}),
        ("sleep", {"value": 4.0}),
        ("land", {}),
    )
    plan = plan_native_run(run, (1.0, 2.0, 0.0), home)
    commands = [item.command for item in plan.items]
    assert commands == [
        mavlink.MAV_CMD_NAV_TAKEOFF,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LOITER_TIME,
        mavlink.MAV_CMD_NAV_LAND,
    ]
    # The wait rides on the waypoint before it; every other step has an item of its own.
    assert plan.completes_at == [0, 1, 1, 2, 3, 4, 5]
    north, east, _ = lla_to_ned(plan.items[1].x / 1e7, plan.items[1].y / 1e7, 0.0, home)
    assert (north, east) == pytest.approx((21.0, 2.0), abs=0.02)
    assert [item.z for item in plan.items] == [10.0, 10.0, 15.0, 12.0, 12.0, 0.0]
    assert plan.items[4].params[0] == 4.0
    assert plan.lands


def test_an_uploaded_mission_reads_back_item_for_item(fc):
    items = [
        MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, z=10.0),
        MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, x=406310000, y=-86570000, z=12.5),
        MissionItem(
            mavlink.MAV_CMD_NAV_LOITER_TIME, params=(5.0, 0, 0, 0), x=406311000, y=-86571000, z=12.5
        ),
        MissionItem(mavlink.MAV_CMD_NAV_LAND, x=406311000, y=-86571000),
    ]
    uploader = MissionUploader(fc)
    uploader.upload(items)
    assert uploader.download() == items
    assert uploader.stats["items_sent"] == len(items) + 1  # ArduPilot's home item 0 first


def test_a_refused_mission_names_the_mav_mission_result(fc):
    odd_frame = MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, frame=mavlink.MAV_FRAME_BODY_FRD)
    with pytest.raises(MissionUploadError, match="MAV_MISSION_UNSUPPORTED_FRAME"):
        MissionUploader(fc).upload([odd_frame])


class Outbox(list):
    def steps(self, status: str) -> list[tuple[int, str]]:
        return [
            (m.index, m.command)
            for m in self
            if isinstance(m, protocol.StepProgress) and m.status == status
        ]

    def missions(self) -> list[str]:
        return [m.status for m in self if isinstance(m, protocol.MissionProgress)]


def start(worker: NativeMissionWorker, mission: list[protocol.Step]) -> None:
    payload = protocol.encode_mission_payload("M1", "A1", [s.to_dict() for s in mission])
    worker.submit(protocol.MissionStart(protocol.new_request_id(), "M1", "A1", payload))


@pytest.fixture
def worker(fc):  # type: ignore[no-untyped-def]
    navigation = NavigationProcessor(fc)
    controller = Controller(fc, navigation, arm_timeout=5)
    outbox = Outbox()
    worker = NativeMissionWorker(
        fc, controller, navigation, outbox.append, time_scale=TIME_SCALE, flight_timeout=120
    )
    worker.outbox = outbox
    worker.start()
    yield worker
    worker.close()


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_worker_flies_a_survey_natively_and_reports_every_step(worker, fc, autopilot):
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("changeN", {"value": 30.0}),
        ("wait_for_flight", {}),
        ("changeE", {"value": 20.0}),
        ("sleep", {"value": 4.0}),
        ("land", {}),
        ("disarm", {}),
    )
    reached: list[int] = []
    fc.add_message_handler(
        lambda m: reached.append(m.seq) if m.get_type() == "MISSION_ITEM_REACHED" else None
    )
    start(worker, mission)
    outbox = worker.outbox
    assert wait_for(lambda: outbox.missions()[-1:] == ["completed"], 30), list(outbox)
    assert outbox.steps("completed") == [(s.index, s.command) for s in mission]
    # Takeoff, two waypoints, loiter, land: from item 1 on ArduPilot, which keeps home in
    # item 0; from item 0 on PX4 (AUTO.MISSION).
    first = 0 if autopilot == "px4" else 1
    assert reached == [first + i for i in range(5)]
    assert not fc.state.armed
    assert fc.state.ned[:2] == pytest.approx((30.0, 20.0), abs=1.0)
    loiter = next(
        m for m in outbox if getattr(m, "command", "") == "sleep" and m.status == "completed"
    )
    assert loiter.duration_s >= 3.0  # simulated seconds hovering


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_stopping_a_native_mission_leaves_auto_and_holds(worker, fc, autopilot):
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("changeN", {"value": 400.0}),
        ("wait_for_flight", {}),
        ("land", {}),
    )
    start(worker, mission)
    outbox = worker.outbox
    assert wait_for(lambda: (1, "takeoff") in outbox.steps("completed"), 20), list(outbox)
    time.sleep(0.3)
    worker.stop_current("stopped by the ground")
    assert wait_for(lambda: outbox.missions()[-1:] == ["stopped"], 10), list(outbox)
    assert outbox.steps("failed") == [(2, "changeN")]
    assert fc.state.flight_mode == fc.guided_mode  # GUIDED, or PX4's hold (LOITER)
    north = fc.state.ned[0]
    time.sleep(0.5)
    assert fc.state.ned[0] < 400 - 50 and abs(fc.state.ned[0] - north) < 15


def test_a_mission_uploads_intact_over_a_link_that_loses_a_third_of_the_messages(tmp_path):
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--param", "SIM_LOSS_PCT=33"],
        log_file=tmp_path / "sim.log",
    )
    fc = MavlinkFlightController(sim.link_url)
    items = [MissionItem(mavlink.MAV_CMD_NAV_TAKEOFF, z=10.0)] + [
        MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, x=406303000 + 100 * i, y=-86575000, z=10.0)
        for i in range(15)
    ]
    try:
        fc.start()
        assert fc.wait_connected(5)
        uploader = MissionUploader(fc, item_timeout=0.3, retries=10)
        uploader.upload(items)
        assert uploader.stats["resends"] > 0 or uploader.stats["items_sent"] > len(items)
        assert uploader.download() == items
    finally:
        fc.stop()
        sim.stop()

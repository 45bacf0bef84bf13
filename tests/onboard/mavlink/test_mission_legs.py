"""Mission legs with a region of interest or a speed on MAVLink drones: flown step by step
through the driver's `point_at`, and natively as mission items, against the simulator."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from onboard import protocol
from onboard.controller import Controller
from onboard.fc.mavlink import CommandRejected
from onboard.mavlink_mission import MissionItem, MissionUploader, native_runs, plan_native_run
from onboard.mission import MissionWorker
from onboard.navigation import NavigationProcessor, ned_to_lla

from .conftest import HOME, TIME_SCALE, wait_for
from .test_native_mission import Outbox, start, steps, worker  # noqa: F401  (fixture)

# Wall time a step's reported duration may gain on a loaded machine (see its use).
SCHEDULING_WALL_S = 1.0


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_lla(north, east, 0.0, HOME)
    return lat, lon


def leg(north: float, east: float, **params: object) -> tuple[str, dict]:
    lat, lon = at(north, east)
    return ("navigate", {"lat": lat, "lon": lon, **params})


def bearing(frm: tuple[float, float], to: tuple[float, float]) -> float:
    return math.degrees(math.atan2(to[1] - frm[1], to[0] - frm[0])) % 360.0


def heading_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.fixture
def step_worker(fc):  # type: ignore[no-untyped-def]
    navigation = NavigationProcessor(fc)
    outbox = Outbox()
    stepper = MissionWorker(
        fc,
        Controller(fc, navigation, arm_timeout=5),
        navigation,
        outbox.append,
        time_scale=TIME_SCALE,
        flight_timeout=120,
    )
    stepper.outbox = outbox
    stepper.start()
    yield stepper
    stepper.close()


def roi_commands(fc) -> list[tuple[int, int]]:  # type: ignore[no-untyped-def]
    acks: list[tuple[int, int]] = []
    roi = (mavlink.MAV_CMD_DO_SET_ROI_LOCATION, mavlink.MAV_CMD_DO_SET_ROI_NONE)

    def on_message(msg) -> None:  # type: ignore[no-untyped-def]
        if msg.get_type() == "COMMAND_ACK" and msg.command in roi:
            acks.append((msg.command, msg.result))

    fc.add_message_handler(on_message)
    return acks


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_leg_with_a_region_of_interest_ends_facing_it(step_worker, fc, autopilot):
    roi = (30.0, 50.0)  # metres north, east of home: off to the side of the leg
    acks = roi_commands(fc)
    yaws: list[float] = []  # every ATTITUDE yaw the simulator reported, for the record
    fc.add_message_handler(
        lambda m: (
            yaws.append(round(math.degrees(m.yaw) % 360, 1)) if m.get_type() == "ATTITUDE" else None
        )
    )
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("wait_for_flight", {}),
        leg(60.0, 0.0, roi=list(at(*roi))),
        ("wait_for_flight", {}),
    )
    start(step_worker, mission)
    outbox = step_worker.outbox
    assert wait_for(lambda: outbox.missions()[-1:] == ["completed"], 30), list(outbox)
    here = fc.state.ned[:2]
    assert here == pytest.approx((60.0, 0.0), abs=3.0)
    # Flying north, the nose was turned to the ROI (south-east of the end point), as the
    # simulator's ATTITUDE reports it; the mission's end then cleared the ROI.
    facing = bearing(here, roi)
    assert wait_for(lambda: heading_error(fc.state.yaw, facing) < 5.0, 3), (facing, yaws, acks)
    assert heading_error(fc.state.yaw, 0.0) > 90.0
    assert acks == [
        (mavlink.MAV_CMD_DO_SET_ROI_LOCATION, mavlink.MAV_RESULT_ACCEPTED),
        (mavlink.MAV_CMD_DO_SET_ROI_NONE, mavlink.MAV_RESULT_ACCEPTED),
    ]


def test_a_leg_without_one_after_a_roi_leg_faces_its_way_again(step_worker, fc):
    roi = (-40.0, -40.0)
    acks = roi_commands(fc)
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("wait_for_flight", {}),
        leg(40.0, 0.0, roi=list(at(*roi))),
        ("wait_for_flight", {}),
        leg(40.0, 50.0),
        ("wait_for_flight", {}),
    )
    start(step_worker, mission)
    outbox = step_worker.outbox
    assert wait_for(lambda: outbox.missions()[-1:] == ["completed"], 30), list(outbox)
    assert fc.state.ned[:2] == pytest.approx((40.0, 50.0), abs=3.0)
    # The second leg cleared the ROI: the nose followed the flight east, not the ROI.
    assert wait_for(lambda: heading_error(fc.state.yaw, 90.0) < 5.0, 3), fc.state.yaw
    assert [command for command, _ in acks] == [
        mavlink.MAV_CMD_DO_SET_ROI_LOCATION,
        mavlink.MAV_CMD_DO_SET_ROI_NONE,
    ]


def test_a_roi_somewhere_no_place_on_earth_is_refused_by_the_autopilot(fc):
    with pytest.raises(CommandRejected, match="FAILED"):
        fc.point_at((0.0, 0.0))
    fc.point_at(at(10.0, 10.0))
    fc.point_at(None)


def test_speed_and_pictures_decide_how_legs_are_split_into_native_runs():
    mission = steps(
        ("takeoff", {"altitude": 10.0}),
        ("changeN", {"value": 20.0}),
        ("wait_for_flight", {}),
        leg(40.0, 0.0, speed=3.0),
        ("wait_for_flight", {}),
        ("sleep", {"value": 2.0}),
        leg(40.0, 40.0),
        ("wait_for_flight", {"photo_distance": 10.0}),
        leg(0.0, 40.0, roi=list(at(0.0, 0.0))),
        ("wait_for_flight", {}),
        ("land", {}),
    )
    runs = [(native, [s.index for s in run]) for native, run in native_runs(mission)]
    assert runs == [
        (True, [0, 1, 2]),
        (True, [3, 4, 5]),  # the paced leg alone: its speed ends with its run
        (False, [6]),  # pictures by distance and a ROI: step by step
        (False, [7]),
        (False, [8]),
        (False, [9]),
        (True, [10]),
    ]
    plan = plan_native_run(mission[3:6], (20.0, 0.0, -10.0), HOME)
    assert [item.command for item in plan.items] == [
        mavlink.MAV_CMD_DO_CHANGE_SPEED,
        mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LOITER_TIME,
    ]
    assert plan.items[0].params == (1.0, 3.0, -1.0, 0.0)
    assert plan.completes_at == [1, 1, 2]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_native_leg_with_a_speed_uploads_a_change_speed_item_and_flies_at_it(
    worker,  # noqa: F811
    fc,
    autopilot,
):
    mission = steps(
        ("arm", {}),
        ("takeoff", {"altitude": 10.0}),
        ("wait_for_flight", {}),
        leg(60.0, 0.0),
        ("wait_for_flight", {}),
        leg(60.0, 60.0, speed=3.0),
        ("wait_for_flight", {}),
    )
    flown: list[tuple[float, float, float]] = []  # north, east, ground speed

    def on_message(msg) -> None:  # type: ignore[no-untyped-def]
        if msg.get_type() == "LOCAL_POSITION_NED":
            flown.append((msg.x, msg.y, math.hypot(msg.vx, msg.vy)))

    fc.add_message_handler(on_message)
    start(worker, mission)
    outbox = worker.outbox
    assert wait_for(lambda: outbox.missions()[-1:] == ["completed"], 40), list(outbox)
    assert outbox.steps("completed") == [(s.index, s.command) for s in mission]
    assert fc.state.ned[:2] == pytest.approx((60.0, 60.0), abs=3.0)
    # The simulator's own speed on the first leg, 3 m/s on the paced one (east of 5 m).
    free = max(speed for north, east, speed in flown if north < 55 and east < 1)
    paced = [speed for north, east, speed in flown if north > 58 and 5 < east < 55]
    paced_s = next(
        m.duration_s
        for m in outbox
        if isinstance(m, protocol.StepProgress) and m.index == 5 and m.status == "completed"
    )
    # 60 m at 3 m/s, in simulated seconds: the step's wall time x TIME_SCALE, its native
    # run's upload (a few round trips) included. Measured 20.2-20.3 s quiet, 20.3-20.7 s
    # with four busy processes on two cores, and 25.5 s beside the whole suite's parallel
    # tests (0.28 s of wall time over the 20). The bound leaves a second of wall time; the
    # speed samples below hold the pace itself.
    assert 60 / 3.0 * 0.9 <= paced_s <= 60 / 3.0 + SCHEDULING_WALL_S * TIME_SCALE, paced_s
    assert free > 8.0, free
    assert paced and max(paced) <= 3.0 * 1.05, paced
    assert min(paced) >= 3.0 * 0.8, paced
    # What the autopilot holds now is the paced leg's own run, the speed item first.
    lat, lon = at(60.0, 60.0)
    on_board = worker.uploader.download()
    assert [item.command for item in on_board] == [
        mavlink.MAV_CMD_DO_CHANGE_SPEED,
        mavlink.MAV_CMD_NAV_WAYPOINT,
    ]
    assert on_board[0] == MissionItem(
        mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, (1.0, 3.0, -1.0, 0.0)
    )
    assert (on_board[1].x, on_board[1].y) == (round(lat * 1e7), round(lon * 1e7))


@pytest.mark.parametrize("autopilot", ["px4"])
def test_the_simulator_triggers_the_camera_by_distance_in_a_mission(fc, autopilot):
    triggers: list[int] = []
    fc.add_message_handler(
        lambda m: triggers.append(m.seq) if m.get_type() == "CAMERA_TRIGGER" else None
    )
    lat, lon = at(40.0, 0.0)
    far = (round(lat * 1e7), round(lon * 1e7))
    here = at(0.0, 0.0)
    items = [
        MissionItem(
            mavlink.MAV_CMD_NAV_TAKEOFF, x=round(here[0] * 1e7), y=round(here[1] * 1e7), z=10.0
        ),
        MissionItem(
            mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION, (10, 0, 1, 0)
        ),
        MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, x=far[0], y=far[1], z=10.0),
        MissionItem(mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, mavlink.MAV_FRAME_MISSION),
        MissionItem(mavlink.MAV_CMD_NAV_WAYPOINT, x=far[0] + 5000, y=far[1], z=10.0),
    ]
    MissionUploader(fc).upload(items)
    fc.command_long(mavlink.MAV_CMD_MISSION_START, 0, len(items) - 1)
    assert wait_for(lambda: fc.state.ned and fc.state.ned[0] > 60.0, 20), fc.state.ned
    # A shot where the leg starts and at 10, 20 and 30 m; the waypoint counts as reached
    # inside its acceptance radius, short of 40 m, and the stop item ends the shots there
    # (none on the 55 m after it).
    assert triggers == [0, 1, 2, 3], triggers

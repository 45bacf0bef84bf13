"""Mission legs with a speed, a region of interest or pictures by distance, flown by the
mission worker through the real UAVTalk driver against the simulator."""

from __future__ import annotations

import queue
import time

import pytest

from firmware.sim import start_simulator
from onboard import protocol
from onboard.controller import Controller
from onboard.fc.uavtalk import UAVTalkFlightController
from onboard.mission import MissionWorker
from onboard.navigation import NavigationProcessor, ned_to_lla
from runtime.processes import wait_for

from .test_driver import HOME, SCALE, LineSwitch


class Camera:
    """The gear manager's camera as the controller sees it: it records where it shot."""

    def __init__(self) -> None:
        self.shots: list[tuple[float, float]] = []

    def take_picture(self, state, context: dict) -> dict:  # type: ignore[no-untyped-def]
        self.shots.append((state.lat, state.lon))
        return {"name": f"IMG_{len(self.shots):04d}.JPG"}


@pytest.fixture
def flight(tmp_path):  # type: ignore[no-untyped-def]
    line = LineSwitch(tmp_path / "arming-line")
    sim = start_simulator(home=HOME, time_scale=SCALE, arming_line=line.path)
    fc = UAVTalkFlightController(sim.url, arming_switch=line, time_scale=SCALE)
    fc.start()
    assert fc.wait_connected(5)
    assert wait_for(lambda: fc.state.home is not None and fc.state.ned is not None, 3)
    navigation = NavigationProcessor(fc)
    camera = Camera()
    messages: queue.Queue = queue.Queue()
    worker = MissionWorker(
        fc,
        Controller(fc, navigation, gear=camera),
        navigation,
        messages.put,
        time_scale=SCALE,
        poll_interval=0.01,
    )
    worker.start()
    yield worker, messages, camera
    worker.close()
    fc.stop()
    sim.stop()


def _fly(worker: MissionWorker, messages: queue.Queue, steps: list[dict]) -> list:
    worker.submit(protocol.mission_start("m1", "a1", steps))
    seen = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        message = messages.get(timeout=deadline - time.monotonic())
        seen.append(message)
        if isinstance(message, protocol.MissionProgress) and message.status not in ("accepted",):
            return seen
    raise AssertionError(f"the mission did not end: {seen}")


def _leg(north: float, **params: object) -> list[dict]:
    lat, lon, _ = ned_to_lla(north, 0.0, 0.0, HOME)
    return [
        {"index": 0, "command": "arm"},
        {"index": 1, "command": "takeoff", "params": {"altitude": 5}},
        {"index": 2, "command": "wait_for_flight"},
        {"index": 3, "command": "navigate", "params": {"lat": lat, "lon": lon, **params}},
        {"index": 4, "command": "wait_for_flight", "params": {}},
    ]


def _duration(messages: list, index: int) -> float:
    done = [
        m
        for m in messages
        if isinstance(m, protocol.StepProgress) and m.index == index and m.status == "completed"
    ]
    assert done, messages
    return done[0].duration_s


def test_a_leg_with_a_speed_is_flown_at_that_speed(flight):
    worker, messages, _ = flight
    fast = _fly(worker, messages, _leg(60.0))
    assert fast[-1].status == "completed", fast[-1]
    quick = _duration(fast, 4)
    slow = _fly(worker, messages, _leg(0.0, speed=3.0))  # back home at 3 m/s
    assert slow[-1].status == "completed", slow[-1]
    paced = _duration(slow, 4)
    # 60 m at 3 m/s is 20 s of flight; the simulator's own pace (10 m/s) takes well under.
    assert 60 / 3.0 * 0.9 <= paced <= 60 / 3.0 + 8, (quick, paced)
    assert quick < paced / 2


def test_pictures_are_taken_every_so_many_metres_of_a_leg(flight):
    worker, messages, camera = flight
    steps = _leg(40.0)
    steps[4]["params"] = {"photo_distance": 10.0}
    done = _fly(worker, messages, steps)
    assert done[-1].status == "completed", done[-1]
    assert 3 <= len(camera.shots) <= 4
    result = next(
        m.result
        for m in done
        if isinstance(m, protocol.StepProgress) and m.index == 4 and m.status == "completed"
    )
    assert result["pictures"] == len(camera.shots)


def test_a_region_of_interest_is_refused_before_anything_flies_on_uavtalk(flight):
    worker, messages, _ = flight
    done = _fly(worker, messages, _leg(20.0, roi=[HOME[0], HOME[1]]))
    assert done[-1].status == "rejected"
    assert "Step 3 (navigate)" in done[-1].error and "region of interest" in done[-1].error
    assert not worker.fc.state.armed

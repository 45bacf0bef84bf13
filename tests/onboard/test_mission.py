"""The mission worker: decode, reject, FIFO steps, wait_for_flight, stop, progress."""

from __future__ import annotations

import base64
import json
import queue
import threading
import time

import pytest

from onboard import protocol
from onboard.controller import Controller
from onboard.mission import MissionWorker
from onboard.navigation import NavigationProcessor

from .fakes import FakeFlightController


class Harness:
    def __init__(self, fc: FakeFlightController | None = None, **options) -> None:
        self.fc = fc or FakeFlightController()
        self.nav = NavigationProcessor(self.fc)
        self.controller = Controller(self.fc, self.nav)
        self.messages: queue.Queue = queue.Queue()
        self.alarms: list[tuple] = []
        self.worker = MissionWorker(
            self.fc,
            self.controller,
            self.nav,
            self.messages.put,
            raise_alarm=lambda level, message, **kw: self.alarms.append((level, message, kw)),
            time_scale=options.pop("time_scale", 100.0),
            poll_interval=0.01,
            **options,
        )
        self.worker.start()

    def send(self, steps: list[dict], mission_id: str = "m1") -> None:
        self.worker.submit(protocol.mission_start(mission_id, "a1", steps))

    def next(self, timeout: float = 5.0):
        return self.messages.get(timeout=timeout)

    def until_mission_status(self, timeout: float = 5.0) -> list:
        seen = []
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.next(deadline - time.monotonic())
            seen.append(message)
            if isinstance(message, protocol.MissionProgress) and message.status != "accepted":
                return seen
        raise AssertionError(f"no final status in {seen}")


@pytest.fixture
def harness():
    h = Harness()
    yield h
    h.worker.close()


def test_a_mission_runs_every_step_in_order_with_progress(harness: Harness) -> None:
    harness.send(
        [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
            {"index": 2, "command": "changeN", "params": {"value": 100}},
            {"index": 3, "command": "sleep", "params": {"value": 1}},
            {"index": 4, "command": "land"},
        ]
    )
    accepted = harness.next()
    assert accepted.status == "accepted" and accepted.decode_ms >= 0
    messages = harness.until_mission_status()
    steps = [(m.index, m.status) for m in messages if isinstance(m, protocol.StepProgress)]
    assert steps == [(i, s) for i in range(5) for s in ("started", "completed")]
    assert messages[-1].status == "completed"
    completed = [
        m for m in messages if isinstance(m, protocol.StepProgress) and m.status == "completed"
    ]
    assert all(m.position is not None and m.duration_s is not None for m in completed)
    assert ("goto", 100.0, 0.0, -10.0) in harness.fc.calls


def test_a_malformed_mission_is_rejected_and_nothing_runs(harness: Harness) -> None:
    bad = {
        "mission_id": "m1",
        "assignment_id": "a1",
        "steps": [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "navigate", "params": {"lat": 123, "lon": 0}},
        ],
    }
    import json

    payload = base64.b64encode(json.dumps(bad).encode()).decode()
    harness.worker.submit(protocol.MissionStart(protocol.new_request_id(), "m1", "a1", payload))
    rejected = harness.next()
    assert rejected.status == "rejected"
    assert "steps[1].params.lat" in rejected.error
    time.sleep(0.1)
    assert harness.messages.empty()
    assert harness.fc.calls == []


def test_a_payload_for_another_mission_is_rejected(harness: Harness) -> None:
    start = protocol.mission_start("m2", "a1", [{"index": 0, "command": "arm"}])
    harness.worker.submit(protocol.MissionStart(start.request_id, "m1", "a1", start.payload))
    assert harness.next().status == "rejected"


def test_wait_for_flight_completes_only_inside_the_cylinder(harness: Harness) -> None:
    harness.fc.move_to(0, 0, 0)
    harness.send(
        [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
            {"index": 2, "command": "changeN", "params": {"value": 50}},
            {
                "index": 3,
                "command": "wait_for_flight",
                "params": {"horizontal_tolerance": 2, "vertical_tolerance": 1},
            },
            {"index": 4, "command": "land"},
        ]
    )
    for _ in range(1 + 3 * 2 + 1):  # accepted, three steps, step 3 started
        message = harness.next()
    assert (message.index, message.status) == (3, "started")
    harness.fc.move_to(47.9, 0, -10)  # 2.1 m short: outside
    harness.fc.move_to(48.5, 0, -11.2)  # vertical error 1.2 m: outside
    time.sleep(0.2)
    assert harness.messages.empty()
    harness.fc.move_to(48.5, 0.5, -10.5)
    done = harness.next()
    assert (done.index, done.status) == (3, "completed")
    assert done.result["target"] == {"north": 50.0, "east": 0.0, "down": -10.0}
    assert harness.until_mission_status()[-1].status == "completed"


def test_stop_interrupts_a_waiting_step_and_runs_nothing_more(harness: Harness) -> None:
    harness.send(
        [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "takeoff"},
            {"index": 2, "command": "wait_for_flight"},
            {"index": 3, "command": "land"},
        ]
    )
    while True:
        message = harness.next()
        if isinstance(message, protocol.StepProgress) and message.index == 2:
            break
    assert harness.worker.current.index == 2
    harness.worker.submit(protocol.MissionStop(protocol.new_request_id(), "m1"))
    rest = harness.until_mission_status()
    assert [(m.index, m.status) for m in rest[:-1]] == [(2, "failed")]
    assert rest[-1].status == "stopped"
    assert ("land",) not in harness.fc.calls
    assert harness.worker.current is None


def test_a_failing_step_stops_the_mission_with_the_reason() -> None:
    h = Harness(FakeFlightController(refuse_arm=True))
    try:
        h.send([{"index": 4, "command": "arm"}, {"index": 5, "command": "takeoff"}])
        messages = [h.next()] + h.until_mission_status()
        assert [(m.index, m.status) for m in messages[1:-1]] == [(4, "started"), (4, "failed")]
        assert "did not arm" in messages[2].error
        assert messages[-1].status == "stopped" and "Step 4 (arm) failed" in messages[-1].error
        assert ("takeoff", 10.0) not in h.fc.calls
    finally:
        h.worker.close()


def test_a_second_mission_is_rejected_while_one_runs(harness: Harness) -> None:
    harness.send([{"index": 0, "command": "sleep", "params": {"value": 100}}])
    assert harness.next().status == "accepted"
    harness.send([{"index": 0, "command": "arm"}], mission_id="m2")
    messages = [harness.next(), harness.next()]
    rejected = [m for m in messages if isinstance(m, protocol.MissionProgress)]
    assert rejected[0].mission_id == "m2" and rejected[0].status == "rejected"


def test_sleep_is_scaled_by_the_time_scale() -> None:
    h = Harness(time_scale=20.0)
    try:
        began = time.monotonic()
        h.send([{"index": 0, "command": "sleep", "params": {"value": 4}}])
        messages = h.until_mission_status()
        elapsed = time.monotonic() - began
        # 4 s at 20x is 0.2 s: measured 0.20-0.21 s, quiet or loaded; unscaled it is 4 s.
        assert 0.19 < elapsed < 3.0
        completed = [m for m in messages if isinstance(m, protocol.StepProgress)][-1]
        assert 3.9 <= completed.duration_s < 8.0  # flight seconds; slack for a busy host
    finally:
        h.worker.close()


def test_virtualalarm_raises_the_alarm_with_the_mission_context(harness: Harness) -> None:
    harness.send(
        [
            {
                "index": 9,
                "command": "virtualalarm",
                "params": {"level": "OUT_MEASURE", "message": "CO2 high"},
            }
        ]
    )
    assert harness.until_mission_status()[-1].status == "completed"
    level, message, kw = harness.alarms[0]
    assert (level, message) == ("OUT_MEASURE", "CO2 high")
    assert kw["context"] == {"mission_id": "m1", "assignment_id": "a1", "index": 9}


def test_the_worker_survives_many_missions_in_parallel_submissions() -> None:
    h = Harness()
    try:
        threads = [
            threading.Thread(target=h.send, args=([{"index": 0, "command": "arm"}], f"m{i}"))
            for i in range(5)
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        statuses = []
        deadline = time.monotonic() + 5
        while (
            time.monotonic() < deadline
            and len([s for s in statuses if s in ("rejected", "completed")]) < 5
        ):
            message = h.next()
            if isinstance(message, protocol.MissionProgress):
                statuses.append(message.status)
        assert statuses.count("accepted") == statuses.count("completed") >= 1
        assert statuses.count("accepted") + statuses.count("rejected") == 5
    finally:
        h.worker.close()


def test_wait_for_flight_after_land_waits_until_the_drone_is_down(harness: Harness) -> None:
    harness.fc.move_to(10, 0, -10)
    harness.send(
        [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "land"},
            {"index": 2, "command": "wait_for_flight"},
            {"index": 3, "command": "disarm"},
        ]
    )
    while True:
        message = harness.next()
        if isinstance(message, protocol.StepProgress) and message.index == 2:
            break
    harness.fc.move_to(10, 0, -1.5)  # inside the 2 m cylinder, but still flying
    time.sleep(0.2)
    assert harness.messages.empty()
    harness.fc.move_to(10, 0, 0)
    assert harness.until_mission_status()[-1].status == "completed"
    assert harness.fc.state.armed is False


def _pause(harness: Harness, action: str, mission_id: str = "m1") -> protocol.MissionProgress:
    harness.worker.submit(protocol.mission_pause(mission_id, action))
    while True:
        message = harness.next()
        if isinstance(message, protocol.MissionProgress):
            return message


def _wait_for_call(fc, call: tuple, since: int = 0, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while call not in fc.calls[since:]:
        assert time.monotonic() < deadline, f"{call} never sent; calls: {fc.calls}"
        time.sleep(0.01)


def test_pause_holds_mid_flight_and_resume_flies_the_step_again_reported_once(
    harness: Harness,
) -> None:
    """Rule: a pause interrupts a waiting step and holds where the drone is; resume heads
    for the paused target again and carries on from that step, each step reported once."""
    harness.fc._state.update(armed=True)  # airborne: armed and above 0.5 m
    harness.fc.move_to(0.0, 0.0, -10.0)
    harness.send(
        [
            {"index": 0, "command": "arm"},
            {"index": 1, "command": "takeoff", "params": {"altitude": 10}},
            {"index": 2, "command": "changeN", "params": {"value": 50}},
            {"index": 3, "command": "wait_for_flight"},
            {"index": 4, "command": "sleep", "params": {"value": 1}},
        ]
    )
    seen = []
    while not (isinstance(m := harness.next(), protocol.StepProgress) and m.index == 3):
        seen.append(m)
    seen.append(m)
    harness.fc.move_to(10.0, 0.0, -10.0)  # on the way north
    paused = _pause(harness, "pause")
    assert paused.status == "paused" and paused.request_id is not None
    _wait_for_call(harness.fc, ("goto", 10.0, 0.0, -10.0))  # held where it was
    assert _pause(harness, "pause").status == "rejected"  # already paused
    calls_before = len(harness.fc.calls)
    assert _pause(harness, "resume").status == "resumed"
    _wait_for_call(harness.fc, ("goto", 50.0, 0.0, -10.0), since=calls_before)
    harness.fc.move_to(50.0, 0.0, -10.0)
    seen += harness.until_mission_status()
    steps = [(m.index, m.status) for m in seen if isinstance(m, protocol.StepProgress)]
    assert steps == [(i, s) for i in range(5) for s in ("started", "completed")]
    assert seen[-1].status == "completed"


def test_a_pause_interrupts_a_sleep_and_a_stop_ends_the_paused_mission_there(
    harness: Harness,
) -> None:
    harness.send(
        [{"index": 0, "command": "sleep", "params": {"value": 100}}, {"index": 1, "command": "arm"}]
    )
    while not (isinstance(m := harness.next(), protocol.StepProgress) and m.status == "started"):
        pass
    assert _pause(harness, "pause").status == "paused"
    time.sleep(0.2)
    assert harness.worker.current.index == 0 and ("arm",) not in harness.fc.calls
    harness.worker.submit(protocol.MissionStop(protocol.new_request_id(), "m1"))
    rest = harness.until_mission_status()
    assert [(m.index, m.status) for m in rest[:-1]] == [(0, "failed")]
    assert rest[-1].status == "stopped"
    assert ("arm",) not in harness.fc.calls


def test_pause_and_resume_without_a_running_mission_are_refused(harness: Harness) -> None:
    refused = _pause(harness, "pause", "nope")
    assert refused.status == "rejected" and "not running" in refused.error
    harness.send([{"index": 0, "command": "sleep", "params": {"value": 100}}])
    while not isinstance(harness.next(), protocol.StepProgress):
        pass
    refused = _pause(harness, "resume")
    assert refused.status == "rejected" and "not paused" in refused.error
    harness.worker.stop_current("test over")


def test_pause_requests_parse_and_unknown_actions_are_refused() -> None:
    request = protocol.mission_pause(7, "pause")
    parsed = protocol.parse_mission_request(json.loads(protocol.encode(request)))
    assert parsed == request
    with pytest.raises(protocol.ProtocolError, match="action"):
        protocol.parse_mission_request({**request.to_dict(), "action": "hover"})
    with pytest.raises(protocol.ProtocolError, match="action"):
        protocol.mission_pause(7, "hover")

"""The fail-safe's decisions, on a flight controller that moves only when told to."""

from __future__ import annotations

import threading

import pytest

from onboard.controller import Controller
from onboard.failsafe import DrainMeter, FailSafe, Limits, energy_to_get_home, parse_bounds
from onboard.navigation import NavigationProcessor

from .fakes import FakeFlightController


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def failsafe_for(fc: FakeFlightController, alarms: list | None = None, **limits) -> tuple:
    clock, stopped = Clock(), []
    failsafe = FailSafe(
        fc,
        lambda level, message, **kw: (alarms if alarms is not None else []).append(
            (level, message, kw)
        ),
        stop_mission=lambda reason: stopped.append(reason) or True,
        limits=Limits(**limits),
        clock=clock,
    )
    return failsafe, clock, stopped


def airborne(north: float = 0.0, east: float = 0.0, altitude: float = 10.0) -> FakeFlightController:
    fc = FakeFlightController()
    fc.arm()
    fc.move_to(north, east, -altitude)
    return fc


def test_the_critical_alarm_repeats_until_acknowledged_and_rearms_on_a_new_battery() -> None:
    fc, alarms = FakeFlightController(), []
    failsafe, clock, _ = failsafe_for(fc, alarms, alarm_repeat=10)
    for remaining in (0.9, 0.5, 0.26, 0.24, 0.2):
        fc.set_battery(remaining)
        failsafe.check_battery()
    assert [a[0] for a in alarms] == ["CRITICAL"]
    assert "25 %" in alarms[0][1] and alarms[0][2]["value"] == 0.24
    clock.now = 10.0
    failsafe.check_battery()
    assert len(alarms) == 2 and "repeated" in alarms[1][1]
    assert failsafe.acknowledge("CRITICAL") and not failsafe.acknowledge("CRITICAL")
    clock.now = 50.0
    failsafe.check_battery()
    assert len(alarms) == 2  # acknowledged: no more repeats
    fc.set_battery(1.0)  # a new battery re-arms the alarm
    failsafe.check_battery()
    fc.set_battery(0.2)
    failsafe.check_battery()
    assert len(alarms) == 3


def test_critical_battery_returns_home_when_the_ground_does_not_take_over() -> None:
    fc = airborne(north=40, altitude=12)
    fc.set_battery(0.2)
    failsafe, clock, stopped = failsafe_for(fc, critical_takeover=30)
    failsafe.check_battery()
    clock.now = 29.0
    failsafe.check_battery()
    assert failsafe.recovery is None
    clock.now = 30.0
    failsafe.check_battery()
    assert failsafe.recovery == "return" and ("goto", 0.0, 0.0, -12) in fc.calls
    assert stopped == ["battery critical and the ground has not taken over"]
    fc.move_to(1.0, 0.5, -12)  # over home: land there
    failsafe.check_recovery()
    assert failsafe.recovery == "land" and fc.calls[-1] == ("land",)


def test_a_ground_that_takes_over_keeps_the_drone() -> None:
    fc = airborne(north=40)
    fc.set_battery(0.2)
    failsafe, clock, _ = failsafe_for(fc, critical_takeover=30)
    failsafe.check_battery()
    failsafe.ground_took_over()
    clock.now = 100.0
    failsafe.check_battery()
    assert failsafe.recovery is None and ("land",) not in fc.calls


def test_a_drone_without_the_energy_to_get_home_lands_where_it_is() -> None:
    fc = airborne(north=300, altitude=10)
    failsafe, clock, _ = failsafe_for(fc, critical_takeover=0.1, return_speed=5)
    for second in range(11):  # 1 % a second: 60 s home + 7 s down need 67 %
        clock.now = float(second)
        fc.set_battery(0.30 - 0.01 * second)
        failsafe.check_battery()
    assert failsafe.drain.rate == pytest.approx(0.01)
    assert failsafe.recovery == "land" and ("land",) in fc.calls
    assert not [c for c in fc.calls if c[0] == "goto"]


def test_the_energy_estimate_is_distance_over_speed_times_drain() -> None:
    fc = airborne(north=30, east=40, altitude=15)
    assert energy_to_get_home(fc.state, 0.002, 5.0) == pytest.approx((50 / 5 + 15 / 1.5) * 0.002)
    meter = DrainMeter(window=30)
    meter.add(0.0, 0.5)
    assert meter.rate is None
    meter.add(100.0, 0.4)  # the first sample fell out of the window
    assert meter.rate is None


def test_an_out_of_bounds_reading_raises_out_measure_once() -> None:
    alarms = []
    failsafe = FailSafe(
        FakeFlightController(),
        lambda level, message, **kw: alarms.append((level, kw)),
        bounds=dict([parse_bounds("CO2::1000")]),
    )
    reading = {"value": 1500.0, "mission_id": "m", "assignment_id": "a", "index": 4}
    assert failsafe.check_reading("CO2", reading)
    assert not failsafe.check_reading("CO2", reading)
    assert not failsafe.check_reading("CO2", {"value": 400.0})
    assert failsafe.check_reading("CO2", {"value": 1001.0})
    assert alarms[0][0] == "OUT_MEASURE" and alarms[0][1]["context"]["index"] == 4
    assert not failsafe.check_reading("temperature", {"value": 1e9})
    with pytest.raises(ValueError, match="SENSOR:LO:HI"):
        parse_bounds("CO2")


def test_link_loss_lands_after_the_timeout_only_when_airborne() -> None:
    fc = FakeFlightController()
    failsafe, clock, stopped = failsafe_for(fc, link_loss_timeout=10, link_loss_action="land")
    failsafe.link_changed(False)
    clock.now = 20.0
    assert failsafe.check_link() is None  # on the ground: nothing to do
    fc.arm()
    fc.move_to(0, 0, -10)
    failsafe.link_changed(True)
    failsafe.link_changed(False)
    clock.now = 25.0
    assert failsafe.check_link() is None
    clock.now = 31.0
    assert failsafe.check_link() == "land"
    assert failsafe.check_link() is None
    assert ("land",) in fc.calls and stopped == ["ground link lost; fail-safe land"]


def test_link_loss_returns_home_by_default_then_lands() -> None:
    fc = airborne(north=50, east=20, altitude=12)
    failsafe, clock, _ = failsafe_for(fc)
    assert failsafe.limits.link_loss_action == "return"
    failsafe.link_changed(False)
    clock.now = 30.0
    assert failsafe.check_link() == "return"
    assert ("goto", 0.0, 0.0, -12) in fc.calls
    failsafe.link_changed(True)  # the link is back: the return goes on
    fc.move_to(0.5, 0.0, -12)
    failsafe.check_recovery()
    assert fc.calls[-1] == ("land",)


def test_hold_hovers_then_returns_at_the_battery_reserve() -> None:
    fc = airborne(north=50, altitude=10)
    fc.set_battery(0.5)
    failsafe, clock, _ = failsafe_for(fc, link_loss_action="hold", battery_reserve=0.3)
    failsafe.link_changed(False)
    clock.now = 30.0
    assert failsafe.check_link() == "hold"
    assert fc.calls[-1] == ("goto", 50.0, 0.0, -10.0)
    failsafe.check_recovery()
    assert failsafe.recovery == "hold"
    fc.set_battery(0.3)
    failsafe.check_recovery()
    assert failsafe.recovery == "return" and fc.calls[-1] == ("goto", 0.0, 0.0, -10.0)


def test_a_completed_mission_returns_and_a_stopped_one_holds() -> None:
    fc = airborne(north=20, altitude=10)
    failsafe, _, _ = failsafe_for(fc)
    failsafe.mission_ended("stopped")
    assert failsafe.recovery == "hold" and fc.calls[-1] == ("goto", 20.0, 0.0, -10.0)
    failsafe.ground_took_over()  # the operator chooses
    assert failsafe.recovery is None
    failsafe.mission_ended("completed")
    assert failsafe.recovery == "return" and fc.calls[-1] == ("goto", 0.0, 0.0, -10.0)


class TickDuringGoto(FakeFlightController):
    """Runs `tick` on another thread, and waits for it, before a goto is sent: the
    agent's supervisor ticking between a take-over's decision and its command, as a
    loaded machine lets it."""

    def __init__(self) -> None:
        super().__init__()
        self.tick = None

    def goto_ned(self, north: float, east: float, down: float) -> None:
        tick, self.tick = self.tick, None
        if tick is not None:
            thread = threading.Thread(target=tick)
            thread.start()
            thread.join(5)
        super().goto_ned(north, east, down)


def test_a_mission_completed_over_home_lands_after_its_return_whenever_the_tick_comes() -> None:
    """Rule: the fail-safe's own commands reach the drone in the order it decides them;
    a landing over home is never overtaken by the return that led to it."""
    fc = TickDuringGoto()
    fc.arm()
    fc.move_to(0.0, 0.0, -10.0)  # the mission ended over home
    failsafe, _, _ = failsafe_for(fc)
    fc.tick = failsafe.check_recovery
    failsafe.mission_ended("completed")
    failsafe.check_recovery()
    assert fc.calls[-2:] == [("goto", 0.0, 0.0, -10.0), ("land",)]
    assert failsafe.recovery == "land"


def test_a_mission_completed_on_the_ground_disarms_at_once() -> None:
    fc = FakeFlightController()
    fc.arm()
    failsafe, _, _ = failsafe_for(fc)
    failsafe.mission_ended("completed")
    assert not fc.state.armed


def test_a_landed_drone_disarms_after_the_delay_but_not_before_take_off() -> None:
    fc = FakeFlightController()
    fc.arm()
    failsafe, clock, _ = failsafe_for(fc, auto_disarm_delay=2)
    clock.now = 100.0
    assert not failsafe.check_landed() and fc.state.armed  # armed, waiting to take off
    fc.move_to(0, 0, -10)
    failsafe.check_landed()
    fc.move_to(0, 0, 0)
    clock.now = 101.0
    assert not failsafe.check_landed()
    clock.now = 102.5
    assert not failsafe.check_landed()
    clock.now = 103.1
    assert failsafe.check_landed() and not fc.state.armed


def test_an_arm_for_the_next_flight_is_not_taken_for_the_last_landing() -> None:
    """The flight controller disarmed itself on landing and a new mission armed it again,
    both between two ticks: the fail-safe never saw the drone disarmed, but the arm was
    asked for, so the landing's auto-disarm does not cut the new flight."""
    fc = FakeFlightController()
    fc.arm()
    failsafe, clock, _ = failsafe_for(fc, auto_disarm_delay=2)
    clock.now = 100.0
    fc.move_to(0, 0, -10)
    failsafe.check_landed()
    fc.move_to(0, 0, 0)
    assert not failsafe.check_landed()  # landed, armed: the delay runs
    fc.disarm()
    Controller(fc, NavigationProcessor(fc), on_arm=failsafe.arm_requested).execute("arm", {})
    assert fc.state.armed
    clock.now = 103.1
    assert not failsafe.check_landed() and fc.state.armed


def test_an_unknown_link_loss_action_is_refused() -> None:
    with pytest.raises(ValueError, match="link loss action"):
        Limits(link_loss_action="panic")


@pytest.mark.parametrize(
    ("then", "recovery", "last_call"),
    [("hold", "hold", ("goto", 20.0, 0.0, -10.0)), ("return", "return", ("goto", 0.0, 0.0, -10.0))],
)
def test_a_stop_request_says_what_the_drone_does_next(then, recovery, last_call) -> None:
    fc = airborne(north=20, altitude=10)
    failsafe, _, _ = failsafe_for(fc)
    failsafe.after_stop = then
    failsafe.mission_ended("stopped")
    assert failsafe.recovery == recovery and fc.calls[-1] == last_call
    assert failsafe.after_stop == "hold"  # once only


def test_a_stop_follow_up_is_checked() -> None:
    from onboard import protocol

    assert protocol.stop_follow_up({"action": "stop"}) == "hold"
    assert protocol.stop_follow_up({"then": "return"}) == "return"
    with pytest.raises(protocol.ProtocolError, match="then"):
        protocol.stop_follow_up({"then": "dance"})


class TwoClocks:
    """The drone's wall clock and monotonic clock, moved together by the test."""

    def __init__(self, wall: float) -> None:
        self.wall, self.mono = wall, 0.0

    def advance(self, seconds: float) -> None:
        self.wall += seconds
        self.mono += seconds


def test_request_age_holds_up_to_a_drone_clock_an_hour_ahead() -> None:
    from onboard.failsafe import GroundClock

    ground_now = 1_767_225_600.0
    drone = TwoClocks(ground_now + 3600)  # the drone's clock is an hour ahead
    clock = GroundClock(window=600, clock=lambda: drone.wall, monotonic=lambda: drone.mono)
    assert clock.offset is None
    assert clock.age(ground_now - 0.2) == 0.0  # the first request is its own reference
    drone.advance(5)
    assert clock.age(ground_now + 5) == pytest.approx(0.0, abs=0.3)  # fresh, not an hour old
    drone.advance(60)
    assert clock.age(ground_now + 65 - 42) == pytest.approx(42, abs=0.3)  # queued 42 s
    assert clock.offset == pytest.approx(3600.0)  # the quickest delivery seen
    drone.advance(601)  # old samples leave the window; a fresh one is the reference
    assert clock.age(ground_now + 666) == pytest.approx(0.0, abs=0.3)


def test_a_command_sent_after_a_stop_is_not_undone_when_the_mission_winds_down() -> None:
    # The ground stops a mission and then asks for a landing on the control channel; the
    # landing can fly before the mission thread has wound the mission down.
    fc = airborne(north=20, altitude=10)
    failsafe, _, _ = failsafe_for(fc)
    failsafe.mission_requested()
    failsafe.stop_requested("hold")
    failsafe.ground_took_over()  # the landing arrives
    fc.land()
    failsafe.mission_ended("stopped")
    assert fc.calls[-1] == ("land",) and failsafe.recovery is None


def test_a_stop_received_after_a_command_still_holds() -> None:
    fc = airborne(north=20, altitude=10)
    failsafe, _, _ = failsafe_for(fc)
    failsafe.mission_requested()
    failsafe.ground_took_over()  # an operator command during the mission
    failsafe.stop_requested("hold")
    failsafe.mission_ended("stopped")
    assert failsafe.recovery == "hold" and fc.calls[-1] == ("goto", 20.0, 0.0, -10.0)


def test_a_mission_stopped_by_a_failed_step_holds_whatever_came_before() -> None:
    # A stop for a mission that was not running leaves nothing pending for the next one.
    fc = airborne(north=20, altitude=10)
    failsafe, _, _ = failsafe_for(fc)
    failsafe.stop_requested("return")
    failsafe.mission_requested()
    failsafe.ground_took_over()
    failsafe.mission_ended("stopped")
    assert failsafe.recovery == "hold" and fc.calls[-1] == ("goto", 20.0, 0.0, -10.0)

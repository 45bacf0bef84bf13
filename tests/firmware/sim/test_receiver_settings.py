"""The simulated board's arming from UAVTalkReceiver channels read through its
ManualControlSettings: the switch family with ArmTime/DisarmTime and the "switch low
before arming again" rule, and the stick gestures."""

from __future__ import annotations

import pytest

from firmware.sim.receiver import ARMED, ARMING, DISARMED, BoardChannels, ReceiverArming
from firmware.sim.telemetry import apply_settings
from onboard.uavtalk import ObjectRegistry, receiver_setup

DEFAULTS = receiver_setup.correct_settings(
    ObjectRegistry.load()["ManualControlSettings"].defaults()
)


def _board(changes: dict[str, str]) -> tuple[ReceiverArming, dict]:
    return ReceiverArming(arming_time_s=3.0), apply_settings(DEFAULTS, changes)


def _feed(receiver: ReceiverArming, settings: dict, mode: str, start: float, end: float) -> str:
    channels = BoardChannels(receiver_setup.channel_values(settings, mode), settings)
    t = start
    while t <= end + 1e-9:
        receiver.feed(channels, t)
        t += 0.05
    return receiver.state


def test_switch_throttle_arms_after_arm_time_and_disarms_on_a_low_switch():
    receiver, settings = _board({"Arming": "Switch+Throttle", "ArmTime": "500"})
    assert _feed(receiver, settings, "arm", 0.0, 0.4) == ARMING
    assert _feed(receiver, settings, "arm", 0.45, 0.6) == ARMED
    assert _feed(receiver, settings, "disarm", 1.0, 1.3) == ARMED  # DisarmTime 500 ms
    assert _feed(receiver, settings, "disarm", 1.35, 1.6) == DISARMED


def test_after_a_cancelled_attempt_the_switch_must_go_low_first():
    receiver, settings = _board({"Arming": "Switch+Throttle"})
    assert _feed(receiver, settings, "arm", 0.0, 0.5) == ARMING
    throttle_up = BoardChannels(receiver_setup.channel_values(settings, "arm"), settings)
    throttle_up[2] = 2000
    assert receiver.feed(throttle_up, 0.55) == DISARMED
    assert _feed(receiver, settings, "arm", 0.6, 5.0) == DISARMED
    assert _feed(receiver, settings, "disarm", 5.05, 5.1) == DISARMED
    assert _feed(receiver, settings, "arm", 5.15, 6.3) == ARMED


@pytest.mark.parametrize("option", list(receiver_setup.GESTURES))
def test_each_stick_gesture_arms_and_its_reverse_disarms(option):
    receiver, settings = _board({"Arming": option})
    assert _feed(receiver, settings, "arm", 0.0, 3.1) == ARMED
    assert _feed(receiver, settings, "safe", 3.2, 9.0) == ARMED
    assert _feed(receiver, settings, "disarm", 9.1, 12.2) == DISARMED


def test_a_gesture_board_ignores_a_switch_it_does_not_read():
    receiver, settings = _board({"Arming": "Yaw Right+Throttle"})
    switch = apply_settings(settings, {"Arming": "Switch+Throttle"})
    channels = BoardChannels(receiver_setup.channel_values(switch, "arm"), settings)
    for i in range(100):
        receiver.feed(channels, i * 0.05)
    assert receiver.state == DISARMED

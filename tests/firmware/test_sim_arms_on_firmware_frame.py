"""The simulated flight controller arms on exactly the frame the firmware sends."""

from __future__ import annotations

from firmware.sim.receiver import ReceiverArming
from onboard.arming_frames import load_frames

from .firmware_tool import emitted_frame, pulses_from_segments

FRAME_S = 0.020


def feed_for(receiver: ReceiverArming, pulses: list[int], start: float, seconds: float) -> float:
    """Feed one frame every 20 ms of simulated time; return the time after the last one."""
    now = start
    for _ in range(round(seconds / FRAME_S)):
        receiver.feed(pulses, now)
        now += FRAME_S
    return now


def test_the_simulator_arms_on_the_firmware_arm_frame_after_the_arming_time() -> None:
    frames = load_frames()
    arm = pulses_from_segments(emitted_frame("arm")["segments"])
    receiver = ReceiverArming(frames)
    now = feed_for(receiver, arm, 0.0, frames.arming_time_s - 0.5)
    assert receiver.state == "Arming"
    feed_for(receiver, arm, now, 1.0)
    assert receiver.state == "Armed"


def test_the_simulator_disarms_on_the_firmware_disarm_frame() -> None:
    frames = load_frames()
    receiver = ReceiverArming(frames)
    now = feed_for(receiver, pulses_from_segments(emitted_frame("arm")["segments"]), 0.0, 3.6)
    assert receiver.state == "Armed"
    disarm = pulses_from_segments(emitted_frame("disarm")["segments"])
    feed_for(receiver, disarm, now, frames.disarming_time_s + 0.5)
    assert receiver.state == "Disarmed"


def test_a_frame_with_throttle_above_minimum_never_arms() -> None:
    frames = load_frames()
    arm = pulses_from_segments(emitted_frame("arm")["segments"])
    throttle = frames.channel_index("throttle")
    for value in (frames.throttle_low_max_us + 1, frames.pulse_neutral_us, frames.pulse_max_us):
        receiver = ReceiverArming(frames)
        pulses = list(arm)
        pulses[throttle] = value
        feed_for(receiver, pulses, 0.0, frames.arming_time_s * 3)
        assert receiver.state == "Disarmed"


def test_the_safe_frame_sent_on_signal_loss_never_arms() -> None:
    frames = load_frames()
    receiver = ReceiverArming(frames)
    feed_for(receiver, pulses_from_segments(emitted_frame("safe")["segments"]), 0.0, 10.0)
    assert receiver.state == "Disarmed"

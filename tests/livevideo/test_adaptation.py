"""The picture size and the encoder's target chosen for the link's bitrate estimate and
round trips (onboard/video_adaptation.py), as plain functions of the measures and the
time."""

from __future__ import annotations

import pytest

from onboard.video_adaptation import (
    Adaptation,
    Size,
    decide,
    encoder_target_bps,
    keyframe_due,
    ladder,
    need_bps,
    observe_rtt,
    pause_s,
    report_round_trip_s,
)

SIZES = ladder(640, 480)
FPS = 15.0


NARROW = Adaptation(narrow=True, least_rtt_s=0.01)


def run(estimates: list[tuple[float, float]], state: Adaptation = NARROW) -> Adaptation:
    """The state after each (time, estimate) in turn, on a narrow link unless told."""
    for now, estimate in estimates:
        state = decide(state, SIZES, FPS, estimate, now)
    return state


def test_the_ladder_halves_the_configured_size_down_to_160_wide():
    assert SIZES == (Size(640, 480), Size(320, 240), Size(160, 120))
    assert ladder(320, 240) == (Size(320, 240), Size(160, 120))
    assert ladder(1280, 720) == (Size(1280, 720), Size(640, 360), Size(320, 180), Size(160, 90))
    assert ladder(160, 120) == (Size(160, 120),)


def test_the_need_is_the_kush_gauge_low_motion_figure():
    assert need_bps(Size(640, 480), 15) == pytest.approx(322_560)
    assert need_bps(Size(320, 240), 15) == pytest.approx(80_640)
    assert need_bps(Size(160, 120), 15) == pytest.approx(20_160)


def test_a_low_estimate_steps_down_once_it_lasted_a_second():
    low = 300_000  # under 640x480's 322.6 kbit/s, over 320x240's
    assert run([(0.0, low), (0.9, low)]).rung == 0
    assert run([(0.0, low), (1.0, low)]).rung == 1
    # One size per second: a collapse to 20 kbit/s takes two steps.
    assert run([(0.0, 20_000), (1.0, 20_000)]).rung == 1
    assert run([(0.0, 20_000), (1.0, 20_000), (1.5, 20_000), (2.5, 20_000)]).rung == 2


def test_a_dip_shorter_than_a_second_changes_nothing():
    state = run([(0.0, 300_000), (0.5, 1_000_000), (1.2, 300_000), (2.0, 300_000)])
    assert state.rung == 0 and state.low_since == 1.2


def test_the_smallest_size_stays_whatever_the_estimate():
    state = run([(t, 1_000.0) for t in range(10)])
    assert state.rung == 2


def test_it_steps_up_at_twice_the_larger_need_held_five_seconds():
    bottom = Adaptation(rung=2, narrow=True)
    bar = 2 * need_bps(Size(320, 240), FPS)  # 161.3 kbit/s
    assert run([(0.0, bar), (4.9, bar)], bottom).rung == 2
    assert run([(0.0, bar), (5.0, bar)], bottom).rung == 1
    # Between the need and the bar (hysteresis): 320x240 would fit, but it stays small.
    between = 1.5 * need_bps(Size(320, 240), FPS)
    assert run([(t, between) for t in range(20)], bottom).rung == 2
    # A dip under the bar restarts the wait.
    assert run([(0.0, bar), (3.0, bar - 1), (6.0, bar), (10.9, bar)], bottom).rung == 2


def test_a_low_estimate_alone_does_not_narrow_the_picture():
    # Jitter on a busy computer lowers the estimate without any queue on the link.
    state = run([(t, 20_000) for t in range(10)], Adaptation())
    assert state.rung == 0 and not state.narrow


def test_a_round_trip_over_the_least_by_200_ms_means_a_queue():
    state = Adaptation()
    for rtt in (0.05, 0.03, 0.2, 0.23):
        state = observe_rtt(state, rtt)
    assert state.least_rtt_s == 0.03 and not state.narrow
    state = observe_rtt(state, 0.24)
    assert state.narrow
    # Narrow until the estimate has held the wide floor for 5 s.
    state = run([(0.0, 249_999), (10.0, 250_000), (14.9, 300_000)], state)
    assert state.narrow
    assert not run([(15.0, 300_000)], state).narrow


def test_the_encoder_follows_the_estimate_down_to_the_floor_of_the_link():
    assert encoder_target_bps(100_000, 1_500_000, narrow=True) == 100_000
    assert encoder_target_bps(5_000, 1_500_000, narrow=True) == 30_000
    assert encoder_target_bps(9_000_000, 1_500_000, narrow=True) == 1_500_000
    assert encoder_target_bps(100_000, 1_500_000, narrow=False) == 250_000
    assert encoder_target_bps(400_000, 1_500_000, narrow=False) == 400_000


def test_a_keyframe_waits_until_the_last_one_crossed_half_the_link():
    assert keyframe_due(None, 0, 50_000, 0.0)
    # 6 250 bytes at half of 100 kbit/s: 1 s.
    assert not keyframe_due(10.0, 6_250, 100_000, 10.9)
    assert keyframe_due(10.0, 6_250, 100_000, 11.0)
    # Never closer than 300 ms, however fast the link.
    assert not keyframe_due(10.0, 100, 10_000_000, 10.2)
    assert keyframe_due(10.0, 100, 10_000_000, 10.3)


def test_a_round_trip_runs_from_the_sender_reports_sending_less_the_receivers_delay():
    # Sent at 10.0 s, answered after the receiver held it 0.25 s (16384/65536), back at 10.7.
    assert report_round_trip_s(10.0, 16_384, 10.7) == pytest.approx(0.45)


def test_no_frame_is_sent_while_more_than_half_a_second_is_queued():
    state = observe_rtt(Adaptation(), 0.05)
    assert pause_s(observe_rtt(state, 0.5)) == 0.0  # 0.45 s queued: narrow, no pause
    assert observe_rtt(state, 0.5).narrow
    assert pause_s(observe_rtt(state, 1.25)) == pytest.approx(1.2)
    assert pause_s(observe_rtt(observe_rtt(state, 1.25), 0.1)) == 0.0

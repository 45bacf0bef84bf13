"""The viewer ticket and the capture time drawn into frames, without any server."""

from __future__ import annotations

from fractions import Fraction

import av
import numpy as np
import pytest

from livevideo import tickets
from onboard import framecode
from onboard.synthetic_camera import render_view_rgb

KEY = b"k" * 32


def test_a_ticket_names_its_drone_and_organisation_and_expires():
    ticket = tickets.mint(KEY, "ACME_1", 7, ttl_s=60, now=1000.0)
    assert tickets.verify(KEY, ticket, "ACME_1", now=1059.0) == tickets.Ticket("ACME_1", 7, 1060)
    with pytest.raises(tickets.TicketError, match="expired"):
        tickets.verify(KEY, ticket, "ACME_1", now=1061.0)
    with pytest.raises(tickets.TicketError, match="another drone"):
        tickets.verify(KEY, ticket, "ACME_2", now=1001.0)
    with pytest.raises(tickets.TicketError, match="signature"):
        tickets.verify(b"x" * 32, ticket, "ACME_1", now=1001.0)


@pytest.mark.parametrize("bad", ["", "abc", "a.b.c", "!!!.???", "YQ.YQ"])
def test_a_malformed_ticket_is_refused(bad):
    with pytest.raises(tickets.TicketError):
        tickets.verify(KEY, bad, "ACME_1")


def test_a_ticket_cannot_be_edited_to_another_organisation():
    payload, signature = tickets.mint(KEY, "ACME_1", 7, ttl_s=60).split(".")
    other = tickets.mint(KEY, "ACME_1", 8, ttl_s=60).split(".")[0]
    with pytest.raises(tickets.TicketError, match="signature"):
        tickets.verify(KEY, f"{other}.{signature}", "ACME_1")
    assert payload != other


def test_crc16_is_ccitt_false():
    # The check value of the CRC catalogue for "123456789".
    assert framecode.crc16(b"123456789") == 0x29B1


def _vp8_round_trip(frames: list[np.ndarray], bitrate: int) -> list[np.ndarray]:
    """Encode with libvpx (VP8) and decode again, as the relay and the browser see it."""
    height, width = frames[0].shape[:2]
    encoder = av.CodecContext.create("libvpx", "w")
    encoder.width, encoder.height, encoder.pix_fmt = width, height, "yuv420p"
    encoder.bit_rate, encoder.time_base = bitrate, Fraction(1, 10)
    decoder = av.CodecContext.create("vp8", "r")
    out = []
    for index, rgb in enumerate(frames):
        frame = av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuv420p")
        frame.pts = index
        for packet in encoder.encode(frame):
            out += [f.to_ndarray(format="gray") for f in decoder.decode(packet)]
    for packet in encoder.encode(None):
        out += [f.to_ndarray(format="gray") for f in decoder.decode(packet)]
    return out


def test_the_capture_time_survives_vp8_at_the_lowest_bitrate():
    times = [1_764_000_000_000 + 100 * i for i in range(10)]
    frames = []
    for i, ms in enumerate(times):
        rgb = render_view_rgb((i * 2.0, 0.0, -20.0), (0.0, 0.0, 0.0, 1.0)).copy()
        framecode.stamp(rgb, ms)
        frames.append(rgb)
    decoded = _vp8_round_trip(frames, bitrate=250_000)
    assert [framecode.read(luma) for luma in decoded] == times


def test_a_damaged_strip_reads_as_no_time():
    rgb = np.full((240, 320, 3), 128, np.uint8)
    framecode.stamp(rgb, 1_764_000_000_123)
    luma = rgb[:, :, 0].copy()
    assert framecode.read(luma) == 1_764_000_000_123
    luma[0:8, 70:80] = 255 - luma[0:8, 70:80]  # one cell flipped
    assert framecode.read(luma) is None
    assert framecode.read(np.zeros((240, 320), np.uint8)) is None


def test_a_recordings_start_pairs_the_clocks_read_together(monkeypatch):
    """A pause between the wall clock's reading and the monotonic clock's (a preempted
    thread) is not taken into the pairing: the tightest reading is kept."""
    from datetime import UTC, datetime

    from livevideo import recording

    readings = iter([10.0, 10.050, 20.0, 20.0004])  # a 50 ms pause, then a tight pair
    walls = iter([datetime(2026, 1, 1, tzinfo=UTC), datetime(2026, 1, 2, tzinfo=UTC)])
    monkeypatch.setattr(recording.time, "monotonic", lambda: next(readings))
    monkeypatch.setattr(recording, "datetime", type("D", (), {"now": lambda tz: next(walls)}))
    wall, monotonic = recording.clock_pair()
    assert wall == datetime(2026, 1, 2, tzinfo=UTC)
    assert monotonic == pytest.approx(20.0002)


@pytest.mark.parametrize(
    ("environ", "expected"),
    [({}, 10), ({"SKYHIVE_LIVE_VIDEO_NICE": ""}, 10), ({"SKYHIVE_LIVE_VIDEO_NICE": "0"}, 0),
     ({"SKYHIVE_LIVE_VIDEO_NICE": " 19 "}, 19)],
)  # fmt: skip
def test_the_publisher_stands_aside_by_ten_unless_told(environ, expected):
    from onboard.live_video import niceness

    assert niceness(environ) == expected


@pytest.mark.parametrize("bad", ["-1", "20", "ten", "1.5"])
def test_a_bad_niceness_is_a_clear_error(bad):
    from onboard.live_video import niceness

    with pytest.raises(SystemExit, match="a whole number from 0 to 19"):
        niceness({"SKYHIVE_LIVE_VIDEO_NICE": bad})


@pytest.mark.parametrize(("setting", "added"), [(None, 10), ("3", 3)])
def test_the_publisher_process_runs_at_its_niceness(setting, added):
    """`python -m onboard.live_video` as the agent starts it, with nothing to publish to."""
    import os
    import subprocess
    import time

    from onboard.live_video import NICE_ENV, LiveVideoConfig
    from runtime.processes import REPO_ROOT, free_port, python_env

    env = python_env()
    env.pop(NICE_ENV, None)
    if setting is not None:
        env[NICE_ENV] = setting
    config = LiveVideoConfig(f"http://127.0.0.1:{free_port()}", "ACME_1", "pw", 160, 120, 5)
    child = subprocess.Popen(config.argv(), stdin=subprocess.PIPE, env=env, cwd=str(REPO_ROOT),
                             stderr=subprocess.DEVNULL)  # fmt: skip
    try:
        ours = os.getpriority(os.PRIO_PROCESS, 0)
        deadline = time.monotonic() + 30
        while os.getpriority(os.PRIO_PROCESS, child.pid) == ours and child.poll() is None:
            assert time.monotonic() < deadline, "the publisher never changed its niceness"
            time.sleep(0.05)
        assert os.getpriority(os.PRIO_PROCESS, child.pid) == min(19, ours + added)
    finally:
        child.kill()
        child.wait(10)

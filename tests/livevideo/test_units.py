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

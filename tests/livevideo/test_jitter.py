"""A lost packet holds the picture back only until the next keyframe (livevideo/jitter.py),
with real VP8 from libvpx, packetised by aiortc's own VP8 packetiser, through aiortc's own
jitter buffer."""

from __future__ import annotations

from fractions import Fraction

import av
import numpy as np
from aiortc.codecs.vpx import Vp8Encoder, vp8_depayload
from aiortc.jitterbuffer import JitterBuffer
from aiortc.rtp import RtpPacket

from livevideo.jitter import skip_gap_before_keyframe, starts_vp8_keyframe, vp8_keyframe_size


def vp8_frames(count: int, keyframes: set[int]) -> list[list[bytes]]:
    """`count` frames of a moving picture as RTP payloads, keyframes where asked."""
    encoder = av.CodecContext.create("libvpx", "w")
    encoder.width, encoder.height, encoder.pix_fmt = 160, 120, "yuv420p"
    encoder.bit_rate, encoder.time_base = 400_000, Fraction(1, 10)
    frames = []
    for index in range(count):
        rgb = np.random.default_rng(index).integers(0, 255, (120, 160, 3), dtype=np.uint8)
        frame = av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuv420p")
        frame.pts = index
        if index in keyframes:
            frame.pict_type = av.video.frame.PictureType.I
        data = b"".join(bytes(p) for p in encoder.encode(frame))
        frames.append(Vp8Encoder._packetize(data, index))
    return frames


def rtp(frames: list[list[bytes]]) -> list[RtpPacket]:
    packets, sequence = [], 1000
    for index, payloads in enumerate(frames):
        for payload in payloads:
            packet = RtpPacket(payload_type=96, sequence_number=sequence,
                               timestamp=index * 9000, payload=payload)  # fmt: skip
            packet._data = vp8_depayload(payload)  # as aiortc's receiver does before the buffer
            packets.append(packet)
            sequence += 1
    return packets


def released(packets: list[RtpPacket], skip: bool) -> list[int]:
    """The timestamps of the frames the buffer releases, with or without the skip."""
    buffer = JitterBuffer(capacity=512, is_video=True)
    out = []
    for packet in packets:
        if skip:
            skip_gap_before_keyframe(buffer, packet.sequence_number, packet.payload)
        _, frame = buffer.add(packet)
        if frame is not None:
            out.append(frame.timestamp)
    return out


def test_the_first_packet_of_a_keyframe_is_told_from_the_others():
    frames = vp8_frames(3, {0, 2})
    assert starts_vp8_keyframe(frames[0][0]) and starts_vp8_keyframe(frames[2][0])
    assert not starts_vp8_keyframe(frames[1][0])
    assert not any(starts_vp8_keyframe(p) for p in frames[0][1:])
    assert not starts_vp8_keyframe(b"") and not starts_vp8_keyframe(b"\x90")


def test_after_a_lost_packet_the_picture_resumes_at_the_next_keyframe():
    frames = vp8_frames(8, {0, 4})
    packets = rtp(frames)
    lost = len(frames[0]) + len(frames[1])  # the first packet of frame 2
    arriving = packets[:lost] + packets[lost + 1 :]
    # Without the skip nothing after the loss comes out (it waits for 512 packets); frame
    # 1, whole, waits for the packet after it too.
    assert released(arriving, skip=False) == [0]
    # With it, frames 1 to 3 are dropped, and the picture goes on from keyframe 4 (frame
    # 7, the last, waits for a packet after it as every last frame does).
    assert released(arriving, skip=True) == [0, 36000, 45000, 54000]
    # Nothing lost: every frame, the skip changes nothing.
    assert released(packets, skip=True) == released(packets, skip=False)
    assert released(packets, skip=True) == [i * 9000 for i in range(7)]


def test_a_keyframes_first_packet_declares_the_pictures_size_and_no_other_packet_does():
    frames = vp8_frames(4, keyframes={0, 2})
    assert vp8_keyframe_size(frames[0][0]) == (160, 120)
    assert vp8_keyframe_size(frames[2][0]) == (160, 120)
    others = [p for i, payloads in enumerate(frames) for p in payloads[i in (0, 2) :]]
    assert others and all(vp8_keyframe_size(p) is None for p in others)
    assert vp8_keyframe_size(b"") is None and vp8_keyframe_size(b"\x10\x00") is None

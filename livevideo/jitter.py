"""A drone's stream resumes at the next keyframe after a lost packet.

aiortc's receiver hands the decoder only whole frames in order: a packet that never comes
holds every later frame back until 512 more packets have arrived (its jitter buffer's
capacity for video), which on a narrow link is most of a minute of a small picture. A
keyframe needs nothing from before it, so when the first packet of a VP8 keyframe arrives
while the buffer still waits for a packet before it, everything before the keyframe is
dropped and the picture goes on from it.

A VP8 keyframe starts with a packet whose payload descriptor ([RFC 7741] section 4.2) has
its S bit set and partition index 0, followed by a frame tag whose P bit (bit 0 of its
first byte) is 0 ([RFC 6386] section 9.1).
"""

from __future__ import annotations

from typing import Any

from aiortc.codecs.vpx import VpxPayloadDescriptor
from aiortc.utils import uint16_add


def starts_vp8_keyframe(payload: bytes) -> bool:
    """Whether an RTP payload is the first packet of a VP8 keyframe."""
    try:
        descriptor, data = VpxPayloadDescriptor.parse(payload)
    except ValueError:
        return False
    return bool(descriptor.partition_start) and descriptor.partition_id == 0 and bool(data) \
        and not data[0] & 1  # fmt: skip


def vp8_keyframe_size(payload: bytes) -> tuple[int, int] | None:
    """The picture size a keyframe's first RTP payload declares, or None for any other
    packet: after the 3-byte frame tag come the start code 9d 01 2a and two 16-bit
    little-endian fields whose low 14 bits are the width and the height ([RFC 6386]
    section 9.1). Read before decoding: an oversize stream is refused unread."""
    if not starts_vp8_keyframe(payload):
        return None
    _, data = VpxPayloadDescriptor.parse(payload)
    if len(data) < 10 or data[3:6] != b"\x9d\x01\x2a":
        return None
    width = int.from_bytes(data[6:8], "little") & 0x3FFF
    height = int.from_bytes(data[8:10], "little") & 0x3FFF
    return width, height


def skip_gap_before_keyframe(buffer: Any, sequence_number: int, payload: bytes) -> bool:
    """Drop what an aiortc JitterBuffer holds before the packet `sequence_number` when that
    packet starts a keyframe and a packet before it is missing; True when it did."""
    origin = buffer._origin
    if origin is None:
        return False
    ahead = uint16_add(sequence_number, -origin)
    if ahead == 0 or ahead >= buffer.capacity or not starts_vp8_keyframe(payload):
        return False
    slots = buffer._packets
    if all(slots[(origin + i) % buffer.capacity] is not None for i in range(ahead)):
        return False
    buffer.remove(ahead)
    return True

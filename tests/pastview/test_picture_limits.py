"""Camera frames declaring more pixels than any camera has are refused before decoding."""

from __future__ import annotations

from pastview.buffer import FrameBuffer, Outcome, is_valid_jpeg

from ..fleet.test_gateway_pictures import jpeg_bomb, small_jpeg


def test_a_frame_declaring_a_huge_image_is_refused_as_corrupt_without_being_decoded():
    assert is_valid_jpeg(small_jpeg())
    assert not is_valid_jpeg(jpeg_bomb())
    buffer = FrameBuffer()
    pose = ([0.0, 0.0, -10.0], [0.0, 0.0, 0.0, 1.0])
    assert buffer.add(1.0, *pose, jpeg_bomb()) is Outcome.CORRUPT_JPEG
    assert buffer.add(1.0, *pose, small_jpeg()) is Outcome.STORED
    assert buffer.stats.corrupt_jpeg == 1 and len(buffer) == 1

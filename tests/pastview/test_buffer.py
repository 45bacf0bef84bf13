import io
import math

import numpy as np
import pytest
from PIL import Image

from pastview.buffer import FrameBuffer, Outcome, is_valid_jpeg
from pastview.geometry import from_yaw, relative_orientation, relative_position

LEVEL = [0.0, 0.0, 0.0, 1.0]


def yawed(deg: float) -> list[float]:
    return from_yaw(math.radians(deg)).tolist()


def test_a_frame_less_than_25_cm_from_the_last_stored_one_is_not_stored(jpeg):
    buffer = FrameBuffer()
    buffer.add(0.0, [0, 0, 0], LEVEL, jpeg)

    outcome = buffer.add(0.5, [0.24, 0, 0], LEVEL, jpeg)

    assert outcome is Outcome.TOO_CLOSE
    assert len(buffer) == 1
    assert buffer.stats.too_close == 1


def test_a_frame_25_cm_from_the_last_stored_one_is_stored(jpeg):
    buffer = FrameBuffer()
    buffer.add(0.0, [0, 0, 0], LEVEL, jpeg)

    assert buffer.add(0.5, [0, 0.15, 0.2], LEVEL, jpeg) is Outcome.STORED
    assert len(buffer) == 2


def test_small_steps_are_measured_from_the_last_stored_frame_not_the_last_seen(jpeg):
    buffer = FrameBuffer()
    outcomes = [buffer.add(i * 0.5, [i * 0.1, 0, 0], LEVEL, jpeg) for i in range(7)]

    stored = [i for i, o in enumerate(outcomes) if o is Outcome.STORED]
    assert stored == [0, 3, 6]


def test_a_turn_of_at_least_10_degrees_in_place_is_stored_and_a_smaller_one_is_not(jpeg):
    buffer = FrameBuffer()
    buffer.add(0.0, [0, 0, 0], yawed(175.0), jpeg)

    assert buffer.add(0.5, [0, 0, 0], yawed(-175.5), jpeg) is Outcome.TOO_CLOSE  # 9.5 deg
    assert buffer.add(1.0, [0, 0, 0], yawed(-174.5), jpeg) is Outcome.STORED  # 10.5 deg


def test_the_oldest_frames_are_dropped_beyond_the_capacity(jpeg):
    buffer = FrameBuffer(capacity=30)
    for i in range(35):
        buffer.add(float(i), [float(i), 0, 0], LEVEL, jpeg)

    frames = buffer.frames()
    assert len(buffer) == 30
    assert frames.ids.tolist() == list(range(5, 35))
    assert frames.timestamps.tolist() == [float(i) for i in range(5, 35)]
    assert buffer.stats.evicted == 5
    assert buffer.get(4) is None
    assert buffer.get(5).pose.ts == 5.0


def test_frames_stay_chronological_and_consistent_across_many_wrap_arounds(jpeg):
    rng = np.random.default_rng(5)
    buffer = FrameBuffer(capacity=7, decode_jpeg=False)
    kept = []
    for i in range(200):
        position = rng.normal(scale=10, size=3)
        orientation = rng.normal(size=4)
        orientation /= np.linalg.norm(orientation)
        if buffer.add(float(i), position, orientation, jpeg) is Outcome.STORED:
            kept.append((position, orientation))

    frames = buffer.frames()
    positions = np.array([p for p, _ in kept[-7:]])
    orientations = np.array([q for _, q in kept[-7:]])
    drone_position, drone_orientation = np.array([1.0, 2.0, -3.0]), np.array(LEVEL)
    assert np.allclose(frames.positions, positions)
    assert np.all(np.diff(frames.timestamps) > 0)
    assert np.allclose(
        frames.relative_positions(drone_position),
        relative_position(positions, orientations, drone_position),
    )
    assert np.allclose(
        frames.relative_orientations(drone_orientation),
        relative_orientation(orientations, drone_orientation),
    )
    assert buffer.frame_at(-1).id == buffer.stats.stored - 1


def test_a_frame_older_than_the_newest_stored_is_dropped_and_counted(jpeg):
    buffer = FrameBuffer()
    buffer.add(10.0, [0, 0, 0], LEVEL, jpeg)

    outcome = buffer.add(9.0, [5, 0, 0], LEVEL, jpeg)

    assert outcome is Outcome.OUT_OF_ORDER
    assert buffer.stats.out_of_order == 1
    assert len(buffer) == 1


def truncated(jpeg: bytes) -> bytes:
    return jpeg[: len(jpeg) // 2]


def garbled(jpeg: bytes) -> bytes:
    return jpeg[:3] + bytes(200) + b"\xff\xd9"


def png(_: bytes) -> bytes:
    out = io.BytesIO()
    Image.new("RGB", (8, 8)).save(out, format="PNG")
    return out.getvalue()


@pytest.mark.parametrize("corrupt", [truncated, garbled, png, lambda _: b"", lambda _: "text"])
def test_a_frame_with_a_corrupt_jpeg_is_dropped_and_counted(jpeg, corrupt):
    buffer = FrameBuffer()

    outcome = buffer.add(0.0, [0, 0, 0], LEVEL, corrupt(jpeg))

    assert outcome is Outcome.CORRUPT_JPEG
    assert buffer.stats.corrupt_jpeg == 1
    assert len(buffer) == 0


def test_a_real_jpeg_passes_the_check_with_and_without_decoding(jpeg):
    assert is_valid_jpeg(jpeg)
    assert is_valid_jpeg(jpeg, decode=False)
    assert not is_valid_jpeg(truncated(jpeg), decode=False)


@pytest.mark.parametrize(
    ("position", "orientation"),
    [
        ([0, 0, float("nan")], LEVEL),
        ([0, 0, 0], [float("nan"), 0, 0, 1]),
        ([0, 0, 0], [0, 0, 0, 0]),
        ([0, 0, 0], [0, 0, 1]),
    ],
)
def test_a_frame_with_a_nan_or_degenerate_pose_is_dropped_and_counted(jpeg, position, orientation):
    buffer = FrameBuffer()

    outcome = buffer.add(0.0, position, orientation, jpeg)

    assert outcome is Outcome.BAD_POSE
    assert buffer.stats.bad_pose == 1
    assert len(buffer) == 0


def test_a_non_unit_quaternion_is_normalised_and_counted(jpeg):
    buffer = FrameBuffer()

    outcome = buffer.add(0.0, [0, 0, 0], [0, 0, 3.0, 4.0], jpeg)

    assert outcome is Outcome.STORED
    assert np.allclose(buffer.frame_at(0).pose.orientation, [0, 0, 0.6, 0.8])
    assert buffer.stats.repaired_quaternions == 1


def test_a_stored_frame_keeps_its_image(jpeg):
    buffer = FrameBuffer()
    buffer.add(0.0, [0, 0, 0], LEVEL, jpeg)

    assert buffer.get(0).jpeg == jpeg


def test_a_zero_capacity_is_refused():
    with pytest.raises(ValueError, match="capacity"):
        FrameBuffer(capacity=0)

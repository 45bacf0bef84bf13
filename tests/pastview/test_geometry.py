import math

import numpy as np
import pytest

from onboard.synthetic_camera import orientation_from_euler
from pastview.geometry import (
    InvalidPose,
    Pose,
    conjugate,
    from_yaw,
    multiply,
    normalise,
    relative_orientation,
    relative_position,
    rotate,
    rotation_matrices,
    wrap_angle,
    yaw,
)


def random_unit_quaternions(n: int, seed: int = 7) -> np.ndarray:
    return normalise(np.random.default_rng(seed).normal(size=(n, 4)))


def test_normalise_scales_a_non_unit_quaternion_to_unit_length():
    q = normalise([0.0, 0.0, 2.0, 2.0])

    assert np.allclose(q, [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)])


@pytest.mark.parametrize(
    "bad", [[float("nan"), 0, 0, 1], [0, 0, 0, 0], [float("inf"), 0, 0, 1], [0, 0, 1]]
)
def test_normalise_refuses_nan_zero_infinite_and_misshapen_quaternions(bad):
    with pytest.raises(InvalidPose):
        normalise(bad)


def test_a_ninety_degree_yaw_turns_north_into_east():
    assert np.allclose(rotate(from_yaw(math.pi / 2), [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])


def test_rotation_matrices_agree_with_quaternion_rotation():
    qs = random_unit_quaternions(50)
    vs = np.random.default_rng(1).normal(size=(50, 3))

    by_matrix = np.einsum("nij,nj->ni", rotation_matrices(qs), vs)

    assert np.allclose(by_matrix, rotate(qs, vs))


def test_the_product_applies_the_right_rotation_first():
    a, b = random_unit_quaternions(2)
    v = np.array([0.3, -1.2, 2.0])

    assert np.allclose(rotate(multiply(a, b), v), rotate(a, rotate(b, v)))


def test_a_quaternion_times_its_conjugate_is_the_identity():
    qs = random_unit_quaternions(10)

    assert np.allclose(multiply(qs, conjugate(qs)), [0.0, 0.0, 0.0, 1.0])


def test_yaw_is_recovered_from_an_orientation_with_roll_and_pitch():
    q = np.array(orientation_from_euler(10.0, -20.0, 130.0))

    assert math.degrees(float(yaw(q))) == pytest.approx(130.0)


def test_wrap_angle_brings_angles_into_minus_pi_to_pi():
    assert np.allclose(
        wrap_angle([3 * math.pi / 2, -3 * math.pi / 2, 0.1]), [-math.pi / 2, math.pi / 2, 0.1]
    )


def test_a_drone_east_of_an_east_facing_frame_is_straight_ahead_in_its_reference():
    rel = relative_position(np.zeros(3), from_yaw(math.pi / 2), [0.0, 2.5, 0.0])

    assert np.allclose(rel, [2.5, 0.0, 0.0])


def test_a_drone_north_of_an_east_facing_frame_is_on_its_left():
    rel = relative_position(np.zeros(3), from_yaw(math.pi / 2), [1.0, 0.0, 0.0])

    assert np.allclose(rel, [0.0, -1.0, 0.0])


def test_relative_position_is_vectorised_over_frames():
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    orientations = np.stack([from_yaw(0.0), from_yaw(math.pi)])

    rel = relative_position(positions, orientations, [2.0, 1.0, -1.0])

    assert np.allclose(rel, [[2.0, 1.0, -1.0], [-1.0, 0.0, -1.0]])


def test_relative_orientation_of_headings_30_and_75_degrees_is_a_45_degree_yaw():
    rel = relative_orientation(from_yaw(math.radians(30)), from_yaw(math.radians(75)))

    assert math.degrees(float(yaw(rel))) == pytest.approx(45.0)


def test_relative_orientation_composes_back_to_the_drone_orientation():
    frames, drones = random_unit_quaternions(20, seed=1), random_unit_quaternions(20, seed=2)

    rel = relative_orientation(frames, drones)

    assert np.allclose(
        rotate(multiply(frames, rel), [1.0, 2.0, 3.0]), rotate(drones, [1.0, 2.0, 3.0])
    )


def test_a_parsed_pose_is_normalised_and_reports_the_repair():
    pose, repaired = Pose.parse(1.5, [1, 2, 3], [0, 0, 0, 2])

    assert repaired
    assert np.allclose(pose.orientation, [0, 0, 0, 1])
    assert pose.to_dict() == {"position": [1.0, 2.0, 3.0], "orientation": [0.0, 0.0, 0.0, 1.0]}


def test_a_unit_pose_is_not_reported_as_repaired():
    _, repaired = Pose.parse(1.5, [1, 2, 3], [0, 0, 0, 1])

    assert not repaired


@pytest.mark.parametrize(
    ("ts", "position", "orientation"),
    [
        (float("nan"), [0, 0, 0], [0, 0, 0, 1]),
        (1.0, [0, float("nan"), 0], [0, 0, 0, 1]),
        (1.0, [0, 0], [0, 0, 0, 1]),
        (1.0, [0, 0, 0], [0, 0, float("nan"), 1]),
        (1.0, [0, 0, 0], "north"),
        ("soon", [0, 0, 0], [0, 0, 0, 1]),
    ],
)
def test_a_pose_with_nan_or_garbage_is_refused(ts, position, orientation):
    with pytest.raises(InvalidPose):
        Pose.parse(ts, position, orientation)

import math

import numpy as np
import pytest

from pastview.evaluation import (
    ConstantDistance,
    ConstantTimeDelay,
    FrameSet,
    Murata,
    Spirit,
    evaluation_from_dict,
    spirit_scores_loop,
)
from pastview.geometry import Pose, from_yaw, normalise

HEADING = math.radians(40.0)
FORWARD = np.array([math.cos(HEADING), math.sin(HEADING), 0.0])
LEFT = np.array([math.sin(HEADING), -math.cos(HEADING), 0.0])
UP = np.array([0.0, 0.0, -1.0])
DRONE = Pose(100.0, np.array([10.0, -4.0, -3.0]), from_yaw(HEADING))


def frames_of(poses: list[tuple[np.ndarray, float]], timestamps=None) -> FrameSet:
    positions = np.array([p for p, _ in poses])
    orientations = np.array([from_yaw(y) for _, y in poses])
    ts = np.arange(len(poses), dtype=float) if timestamps is None else np.asarray(timestamps)
    return FrameSet.from_arrays(ts, positions, orientations)


def pose_at(position, yaw_rad: float, ts: float = 0.0) -> Pose:
    return Pose(ts, np.asarray(position, dtype=float), from_yaw(yaw_rad))


def test_spirit_scores_zero_for_a_frame_directly_behind_the_drone_at_the_reference_distance():
    frames = frames_of([(DRONE.position - 2.5 * FORWARD, HEADING)])

    assert Spirit().scores(frames, DRONE)[0] == pytest.approx(0.0, abs=1e-12)


def test_spirit_prefers_the_frame_directly_behind_at_2_5_m_over_every_other_candidate():
    candidates = [
        (DRONE.position - 1.0 * FORWARD, HEADING),  # too close
        (DRONE.position - 5.0 * FORWARD, HEADING),  # too far
        (DRONE.position - 2.5 * FORWARD, HEADING),  # the ideal view
        (DRONE.position + 2.5 * LEFT, HEADING - math.pi / 2),  # from the side, looking at it
        (DRONE.position + 2.5 * FORWARD, HEADING),  # ahead: the drone is behind the camera
        (DRONE.position - 2.5 * FORWARD, HEADING + math.radians(30)),  # turned away
        (DRONE.position - 2.5 * FORWARD + 1.0 * LEFT, HEADING),  # off-centre
    ]

    index, score = Spirit().select(frames_of(candidates), DRONE)

    assert index == 2
    assert score == pytest.approx(0.0, abs=1e-12)


def test_spirit_terms_match_a_hand_computed_off_centre_case():
    # Frame at the origin facing north; drone 2.5 m ahead and 1 m to the right, same yaw.
    frames = frames_of([(np.zeros(3), 0.0)])
    drone = pose_at([2.5, 1.0, 0.0], 0.0)

    terms = Spirit().terms(frames, drone)
    score = Spirit().scores(frames, drone)[0]

    distance = math.sqrt(2.5**2 + 1.0)
    assert terms["centrality"][0] == pytest.approx(1.0 / 2.5)
    assert terms["direction"][0] == pytest.approx(0.0)
    assert terms["distance"][0] == pytest.approx(((distance - 2.5) / 2.5) ** 2)
    assert score == pytest.approx(4 * 0.4 + 8 * ((distance - 2.5) / 2.5) ** 2)


def test_spirit_relative_yaw_term_is_the_squared_yaw_difference_in_radians():
    frames = frames_of([(np.zeros(3), math.radians(10))])
    drone = pose_at([2.5, 0.0, 0.0], math.radians(-20))

    terms = Spirit().terms(frames, drone)

    assert terms["direction"][0] == pytest.approx(math.radians(30) ** 2)


def test_spirit_counts_a_drone_behind_the_camera_as_wholly_off_centre():
    frames = frames_of([(np.zeros(3), 0.0)])
    drone = pose_at([-2.5, 0.0, 0.0], 0.0)

    assert Spirit().terms(frames, drone)["centrality"][0] == pytest.approx(1.0)


def test_spirit_frame_to_current_terms_use_the_displayed_frame():
    frames = frames_of([(np.array([3.0, 4.0, 0.0]), math.pi / 2)])
    current = pose_at([0.0, 0.0, 0.0], 0.0)

    terms = Spirit().terms(frames, DRONE, current)

    assert terms["direction_with_current"][0] == pytest.approx((math.pi / 2) ** 2)
    assert terms["distance_with_current"][0] == pytest.approx(5.0 / 2.5)


def test_spirit_with_a_camera_tilted_down_centres_a_drone_below_its_axis():
    frames = frames_of([(np.zeros(3), 0.0)])
    drone = pose_at([2.0, 0.0, 2.0], 0.0)  # ahead and 2 m lower (NED)

    level = Spirit().terms(frames, drone)["centrality"][0]
    tilted = Spirit(camera_pitch_down_deg=45.0).terms(frames, drone)["centrality"][0]

    assert level == pytest.approx(2.0 / 2.5)
    assert tilted == pytest.approx(0.0, abs=1e-9)


def test_the_current_frame_terms_make_spirit_keep_the_displayed_frame_over_a_slightly_better_one():
    # The displayed frame is 2.4 m behind; the ideal one, 2.5 m behind, is 10 cm away
    # from it: its distance-to-current term (2 * 0.1 / 2.5) outweighs the displayed
    # frame's distance term (8 * (0.1 / 2.5)^2).
    frames = frames_of(
        [(DRONE.position - 2.4 * FORWARD, HEADING), (DRONE.position - 2.5 * FORWARD, HEADING)]
    )
    current = pose_at(DRONE.position - 2.4 * FORWARD, HEADING)

    assert Spirit().select(frames, DRONE)[0] == 1
    assert Spirit().select(frames, DRONE, current)[0] == 0


@pytest.mark.parametrize("with_current", [False, True])
def test_vectorised_spirit_equals_the_per_frame_loop_on_random_data(with_current):
    rng = np.random.default_rng(2016)
    n = 500
    positions = rng.normal(scale=5.0, size=(n, 3))
    orientations = normalise(rng.normal(size=(n, 4)))
    frames = FrameSet.from_arrays(np.arange(n, dtype=float), positions, orientations)
    spirit = Spirit(
        coeff_centrality=rng.uniform(0, 10),
        coeff_direction=rng.uniform(0, 10),
        coeff_distance=rng.uniform(0, 10),
        coeff_direction_with_current=rng.uniform(0, 10),
        coeff_distance_with_current=rng.uniform(0, 10),
        ref_distance=rng.uniform(0.5, 5),
        camera_pitch_down_deg=rng.uniform(0, 60),
    )
    drone, _ = Pose.parse(1000.0, rng.normal(size=3), rng.normal(size=4))
    current, _ = Pose.parse(999.0, rng.normal(size=3), rng.normal(size=4))
    current = current if with_current else None

    vectorised = spirit.scores(frames, drone, current)
    loop = spirit_scores_loop(
        spirit, positions.tolist(), [tuple(q) for q in orientations.tolist()], drone, current
    )

    assert np.allclose(vectorised, loop, rtol=1e-9, atol=1e-9)
    assert spirit.select(frames, drone, current)[0] == int(np.argmin(loop))


def test_constant_time_delay_picks_the_frame_closest_to_the_reference_age():
    frames = frames_of([(np.zeros(3), 0.0)] * 10, timestamps=np.arange(10.0))
    drone = pose_at([0, 0, 0], 0.0, ts=10.0)

    index, score = ConstantTimeDelay(ref_delay_s=2.4).select(frames, drone)

    assert index == 8  # 10 - 2.4 = 7.6: frame at t=8 is 0.4 s off, t=7 is 0.6 s off
    assert score == pytest.approx(0.4)


@pytest.mark.parametrize(("pose_ts", "expected"), [(0.5, 0), (100.0, 9)])
def test_constant_time_delay_falls_back_to_the_oldest_or_newest_frame(pose_ts, expected):
    frames = frames_of([(np.zeros(3), 0.0)] * 10, timestamps=np.arange(10.0) + 5.0)

    index, _ = ConstantTimeDelay(ref_delay_s=2.0).select(frames, pose_at([0, 0, 0], 0, pose_ts))

    assert index == expected


def test_constant_time_delay_binary_search_agrees_with_scoring_every_frame():
    rng = np.random.default_rng(3)
    ts = np.sort(rng.uniform(0, 100, size=300))
    frames = FrameSet.from_arrays(ts, np.zeros((300, 3)), np.tile([0.0, 0, 0, 1], (300, 1)))
    function = ConstantTimeDelay(ref_delay_s=3.0)
    for pose_ts in rng.uniform(-10, 110, size=200):
        drone = pose_at([0, 0, 0], 0, pose_ts)
        scores = function.scores(frames, drone)
        index, score = function.select(frames, drone)
        assert score == pytest.approx(scores.min())


def test_constant_distance_picks_the_frame_nearest_the_reference_distance():
    frames = frames_of(
        [(DRONE.position - d * FORWARD, HEADING + 1.0) for d in (0.5, 1.9, 2.7, 4.0)]
        + [(DRONE.position + 2.45 * UP, 0.0)]
    )

    index, score = ConstantDistance(ref_distance=2.5).select(frames, DRONE)

    assert index == 4
    assert score == pytest.approx(0.05)


def test_murata_picks_the_frame_at_the_reference_height_and_tilt_behind_the_drone():
    horizontal = math.sqrt(2.5**2 - 1.0)  # 1 m up at 2.5 m: tilt asin(0.4), about 23.6 deg
    candidates = [
        (DRONE.position - 2.5 * FORWARD, HEADING),  # level: no height, no tilt
        (DRONE.position - horizontal * FORWARD + 1.0 * UP, HEADING),  # the reference view
        (DRONE.position - 1.0 * FORWARD + 2.3 * UP, HEADING),  # too high and steep
        (DRONE.position - horizontal * FORWARD + 1.0 * UP, HEADING + 1.2),  # wrong azimuth
    ]

    index, score = Murata().select(frames_of(candidates), DRONE)

    assert index == 1
    assert score == pytest.approx(0.0, abs=1e-3)


def test_murata_height_term_counts_the_viewpoint_above_the_drone():
    frames = frames_of([(np.array([-2.0, 0.0, -2.0]), 0.0)])  # 2 m up, 2 m behind
    drone = pose_at([0.0, 0.0, 0.0], 0.0)
    only_height = Murata(coeff_azimuth=0, coeff_tilt=0, coeff_distance=0, ref_height=1.0)
    only_tilt = Murata(coeff_height=0, coeff_azimuth=0, coeff_distance=0, ref_tilt_deg=0.0)

    assert only_height.scores(frames, drone)[0] == pytest.approx(1.0)  # ((2 - 1) / 1)^2
    assert only_tilt.scores(frames, drone)[0] == pytest.approx((math.pi / 4) ** 2)


@pytest.mark.parametrize("function", [ConstantTimeDelay(), ConstantDistance(), Murata(), Spirit()])
def test_every_function_round_trips_through_a_dict(function):
    data = function.to_dict()

    assert evaluation_from_dict(data) == function
    assert data["function"] == function.name


def test_spirit_defaults_are_the_published_coefficients():
    assert Spirit().to_dict() == {
        "function": "spirit",
        "coeff_centrality": 4.0,
        "coeff_direction": 2.0,
        "coeff_distance": 8.0,
        "coeff_direction_with_current": 1.0,
        "coeff_distance_with_current": 2.0,
        "ref_distance": 2.5,
        "camera_pitch_down_deg": 0.0,
    }


def test_a_zero_time_delay_is_allowed_and_picks_the_newest_frame():
    frames = frames_of([(np.zeros(3), 0.0)] * 3, timestamps=[1.0, 2.0, 3.0])

    function = evaluation_from_dict({"function": "constant_time_delay", "ref_delay_s": 0})

    assert function.select(frames, pose_at([0, 0, 0], 0.0, ts=3.2))[0] == 2


def test_partial_settings_take_defaults_for_the_rest():
    assert evaluation_from_dict({"function": "spirit", "coeff_distance": 3}) == Spirit(
        coeff_distance=3
    )


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"function": "astrology"}, "unknown evaluation function"),
        ({"function": "spirit", "coeff_luck": 1.0}, "unknown parameter"),
        ({"function": "spirit", "coeff_distance": float("nan")}, "finite"),
        ({"function": "spirit", "coeff_distance": -1.0}, "negative"),
        ({"function": "spirit", "ref_distance": 0.0}, "positive"),
        ({"function": "murata", "ref_height": "high"}, "number"),
        ({"function": "murata", "ref_height": -1.0}, "positive"),
        ({"function": "constant_time_delay", "ref_delay_s": -0.5}, "negative"),
        ({"function": "constant_distance", "ref_distance": True}, "number"),
        ("spirit", "object"),
    ],
)
def test_bad_evaluation_settings_are_refused_with_a_clear_message(data, message):
    with pytest.raises(ValueError, match=message):
        evaluation_from_dict(data)

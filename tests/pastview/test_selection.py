import base64
import io
import json
import math

import numpy as np
import pytest
from PIL import Image

from onboard.synthetic_camera import render_view
from pastview.evaluation import ConstantTimeDelay, Spirit
from pastview.geometry import from_yaw
from pastview.selection import PastView, PastViewSettings

NORTH = [0.0, 0.0, 0.0, 1.0]


def frame_message(ts: float, position, orientation=NORTH, jpeg: bytes | None = None) -> dict:
    if jpeg is None:
        jpeg = render_view(tuple(position), tuple(orientation), width=48, height=36)
    return {
        "ts": ts,
        "pose": {"position": list(position), "orientation": list(orientation)},
        "jpeg": base64.b64encode(jpeg).decode("ascii"),
    }


def fly_north(view: PastView, *, seconds: float, hz: float = 30.0, speed: float = 1.0) -> None:
    for k in range(int(seconds * hz)):
        t = k / hz
        view.add_frame(frame_message(t, [speed * t, 0.0, -2.0]))


def test_with_no_frame_yet_the_update_says_so_and_carries_no_image():
    view = PastView()

    update = view.update_pose(1.0, [0, 0, -2], NORTH)

    assert update["frame"] is None
    assert update["relative"] is None
    assert update["jpeg"] is None
    assert update["tracking"] == "tracked"


def test_the_frame_2_5_m_behind_is_chosen_with_the_drone_straight_ahead_in_it():
    view = PastView()
    fly_north(view, seconds=10)

    update = view.update_pose(10.0, [10.0, 0.0, -2.0], NORTH)

    assert update["frame"]["pose"]["position"] == [7.5, 0.0, -2.0]
    assert update["frame"]["score"] == pytest.approx(0.0)
    assert np.allclose(update["relative"]["position"], [2.5, 0.0, 0.0])
    assert np.allclose(update["relative"]["orientation"], [0.0, 0.0, 0.0, 1.0])


def test_the_image_is_sent_only_when_the_chosen_frame_changes():
    view = PastView()
    fly_north(view, seconds=10)

    first = view.update_pose(10.0, [10.0, 0.0, -2.0], NORTH)
    same = view.update_pose(10.005, [10.001, 0.0, -2.0], NORTH)
    moved = view.update_pose(10.010, [9.0, 0.0, -2.0], NORTH)

    assert first["changed"] and first["jpeg"] is not None
    assert not same["changed"] and same["jpeg"] is None
    assert same["frame"]["id"] == first["frame"]["id"]
    assert moved["changed"] and moved["frame"]["id"] != first["frame"]["id"]
    image = Image.open(io.BytesIO(base64.b64decode(moved["jpeg"])))
    assert image.format == "JPEG"
    assert base64.b64decode(moved["jpeg"]) == view.buffer.get(moved["frame"]["id"]).jpeg


def test_video_at_30_hz_is_downsampled_to_2_hz_by_default():
    view = PastView()
    fly_north(view, seconds=3, hz=30.0, speed=2.0)

    assert len(view.buffer) == 6  # t = 0, 0.5, ... 2.5
    assert view.buffer.frames().timestamps.tolist() == [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
    assert view.stats.frames_downsampled == 84


def test_the_downsampling_rate_is_configurable_and_can_be_switched_off():
    every = PastView(PastViewSettings(video_hz=0))
    fast = PastView(PastViewSettings(video_hz=10))
    fly_north(every, seconds=1, speed=10.0)
    fly_north(fast, seconds=1, speed=10.0)

    assert len(every.buffer) == 30
    assert len(fast.buffer) == 10


def test_the_live_view_gets_the_latest_downsampled_frame():
    view = PastView()
    fly_north(view, seconds=1.2)

    assert view.live_frame()["ts"] == pytest.approx(1.0)


def test_a_corrupt_frame_never_reaches_the_live_view(jpeg):
    view = PastView()
    view.add_frame(frame_message(0.0, [0, 0, -2], jpeg=jpeg))

    view.add_frame(frame_message(1.0, [5, 0, -2], jpeg=jpeg[: len(jpeg) // 2]))

    assert view.live_frame()["ts"] == 0.0


def test_tracking_loss_is_reported_and_keeps_the_displayed_frame_until_found():
    view = PastView()
    fly_north(view, seconds=10)
    shown = view.update_pose(10.0, [10.0, 0.0, -2.0], NORTH)

    lost = view.update_pose(10.005, [10.0, 0.0, -2.0], NORTH)
    still_lost = view.update_pose(10.010, [10.0, 0.0, -2.0], NORTH)
    found = view.update_pose(10.015, [8.0, 0.0, -2.0], NORTH)

    assert (lost["tracking"], lost["event"]) == ("lost", "lost")
    assert (still_lost["tracking"], still_lost["event"]) == ("lost", None)
    assert lost["frame"]["id"] == shown["frame"]["id"] and lost["jpeg"] is None
    assert lost["frame"]["score"] is None
    assert (found["tracking"], found["event"]) == ("tracked", "found")
    assert found["frame"]["id"] != shown["frame"]["id"]


def test_frames_arriving_while_tracking_is_lost_are_not_stored():
    view = PastView(PastViewSettings(video_hz=0))
    view.update_pose(0.0, [0, 0, -2], NORTH)
    view.update_pose(0.1, [0, 0, -2], NORTH)  # lost

    stored = view.add_frame(frame_message(0.2, [0, 0, -2]))

    assert not stored
    assert view.stats.frames_untracked == 1
    assert len(view.buffer) == 0


@pytest.mark.parametrize(
    "message",
    [
        "not a dict",
        {"ts": 1.0, "pose": {"position": [0, 0, 0]}, "jpeg": ""},
        {"ts": "later", "pose": {"position": [0, 0, 0], "orientation": NORTH}, "jpeg": ""},
        {"ts": float("nan"), "pose": {"position": [0, 0, 0], "orientation": NORTH}, "jpeg": ""},
        {"ts": 1.0, "pose": {"position": [0, 0, 0], "orientation": NORTH}, "jpeg": "!!not64"},
        {"ts": 1.0, "pose": {"position": [0, 0, 0], "orientation": NORTH}, "jpeg": 12},
        {"ts": 1.0, "pose": [0, 0, 0], "jpeg": ""},
    ],
)
def test_a_malformed_frame_message_is_counted_and_dropped(message):
    view = PastView()

    assert view.add_frame(message) is False
    assert view.stats.frames_malformed == 1


def test_bad_frames_are_dropped_and_counted_while_the_view_keeps_running(jpeg):
    view = PastView(PastViewSettings(video_hz=0))
    good = frame_message(1.0, [0, 0, -2])
    view.add_frame(good)

    view.add_frame(frame_message(2.0, [5, 0, -2], jpeg=b"\xff\xd8\xff broken"))
    view.add_frame(frame_message(0.5, [9, 0, -2]))
    view.add_frame(frame_message(3.0, [7, 0, -2], [float("nan"), 0, 0, 1], jpeg=jpeg))
    view.add_frame(frame_message(4.0, [3, 0, -2], orientation=[0, 0, 0, 5.0]))
    update = view.update_pose(5.0, [5.5, 0, -2], NORTH)

    status = view.status()
    assert status["buffer"]["corrupt_jpeg"] == 1
    assert status["frames_out_of_order"] == 1
    assert status["buffer"]["bad_pose"] == 1
    assert status["buffer"]["repaired_quaternions"] == 1
    assert status["frames_stored"] == 2
    assert update["frame"]["pose"]["position"] == [3.0, 0.0, -2.0]


@pytest.mark.parametrize(
    ("position", "orientation"),
    [([0, float("nan"), 0], NORTH), ([0, 0, 0], [0, 0, 0, 0]), ([0, 0, 0], [float("nan")] * 4)],
)
def test_a_nan_pose_is_counted_and_produces_no_update(position, orientation):
    view = PastView()

    assert view.update_pose(1.0, position, orientation) is None
    assert view.stats.poses_bad == 1


def test_a_non_unit_pose_quaternion_is_normalised():
    view = PastView()

    update = view.update_pose(1.0, [0, 0, 0], [0, 0, 0, 2.0])

    assert update["pose"]["orientation"] == [0.0, 0.0, 0.0, 1.0]
    assert view.stats.quaternions_repaired == 1


def test_an_older_pose_than_the_last_is_dropped():
    view = PastView()
    view.update_pose(2.0, [0, 0, 0], NORTH)

    assert view.update_pose(1.0, [1, 0, 0], NORTH) is None
    assert view.stats.poses_out_of_order == 1


def test_switching_the_evaluation_function_takes_effect_on_the_next_pose():
    view = PastView()
    fly_north(view, seconds=10)
    spirit = view.update_pose(10.0, [10.0, 0.0, -2.0], NORTH)

    view.set_evaluation(ConstantTimeDelay(ref_delay_s=6.0))
    delayed = view.update_pose(10.005, [10.001, 0.0, -2.0], NORTH)

    assert spirit["function"] == "spirit"
    assert delayed["function"] == "constant_time_delay"
    assert delayed["frame"]["ts"] == pytest.approx(4.0)
    assert delayed["changed"]


def test_updates_are_strict_json():
    view = PastView()
    fly_north(view, seconds=5)
    updates = [view.update_pose(5.0, [5, 0, -2], NORTH), view.update_pose(5.1, [5, 0, -2], NORTH)]

    for update in updates:
        json.dumps(update, allow_nan=False)


def test_settings_round_trip_through_a_dict():
    settings = PastViewSettings(
        capacity=100, video_hz=5.0, evaluation=Spirit(coeff_distance=3.0, ref_distance=4.0)
    )

    data = json.loads(json.dumps(settings.to_dict()))

    assert PastViewSettings.from_dict(data) == settings


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"capacity": 0}, "capacity"),
        ({"capacity": 2.5}, "capacity"),
        ({"video_hz": -1}, "video_hz"),
        ({"min_yaw_deg": float("inf")}, "min_yaw_deg"),
        ({"colour": "red"}, "unknown setting"),
        ({"evaluation": {"function": "nope"}}, "unknown evaluation function"),
    ],
)
def test_bad_settings_are_refused_with_a_clear_message(data, message):
    with pytest.raises(ValueError, match=message):
        PastViewSettings.from_dict(data)


def test_a_drone_flying_a_square_is_seen_from_behind_on_every_straight_leg():
    """Simulated square flight: 30 Hz camera, 200 Hz poses, 8 m legs at 1 m/s."""
    view = PastView()
    side, speed, frame_hz, pose_hz = 8.0, 1.0, 30.0, 200.0
    corners = [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side), (0.0, 0.0)]
    legs = []
    for (n0, e0), (n1, e1) in zip(corners, corners[1:], strict=False):
        legs.append(((n0, e0), (n1, e1), math.atan2(e1 - e0, n1 - n0)))
    leg_time = side / speed

    def pose_at(t: float):
        leg = min(int(t // leg_time), 3)
        (n0, e0), (n1, e1), heading = legs[leg]
        f = min((t - leg * leg_time) / leg_time, 1.0)
        return [n0 + f * (n1 - n0), e0 + f * (e1 - e0), -2.0], from_yaw(heading).tolist()

    end = 4 * leg_time
    next_frame = 0.0
    updates = []
    for k in range(int(end * pose_hz)):
        t = k / pose_hz
        while next_frame <= t:
            position, orientation = pose_at(next_frame)
            view.add_frame(frame_message(next_frame, position, orientation))
            next_frame += 1.0 / frame_hz
        position, orientation = pose_at(t)
        updates.append((t, view.update_pose(t, position, orientation)))

    with_frame = [u for _, u in updates if u["frame"] is not None]
    assert len(with_frame) > 0.95 * len(updates)
    # Mid-leg, once 2.5 m of the leg is behind, the chosen view is from behind the drone.
    for t, update in updates:
        into_leg = t % leg_time
        if 3.5 <= into_leg <= leg_time - 0.5 and t > leg_time:
            forward, lateral, _ = update["relative"]["position"]
            assert 1.5 < forward < 3.5, (t, update["relative"])
            assert abs(lateral) < 0.5, (t, update["relative"])
    changes = [u for _, u in updates if u["changed"]]
    assert all(u["jpeg"] for u in changes)
    assert sum(1 for _, u in updates if u["jpeg"]) == len(changes)
    assert 10 < len(changes) < 200

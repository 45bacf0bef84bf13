"""The agent's camera and pose stream (onboard/video.py) and the teleoperation geometry, alone."""

from __future__ import annotations

import io
import math
import threading
import time

import pytest
from PIL import Image

from onboard import protocol
from onboard.fc.base import VehicleState
from onboard.video import POSE_OBJECT, PoseSource, VideoConfig, VideoStreamer
from pastview.teleop import BadInput, Stick, commands_for, heading_of
from runtime.processes import wait_for

pytestmark = pytest.mark.usefixtures("no_snapshots_from_earlier_tests")


class Clock:
    """The vehicle state as the flight controller would leave it, changed by the test."""

    def __init__(self, **fields: object) -> None:
        self.state = VehicleState(updated_at=time.monotonic(), **fields)  # type: ignore[arg-type]

    def __call__(self) -> VehicleState:
        return self.state


def test_no_pose_is_sampled_before_the_flight_controller_gives_one():
    source = PoseSource(Clock(), VideoConfig())
    assert source.sample() is None


def test_the_pose_jitters_like_a_motion_capture_and_repeats_when_it_goes_stale():
    clock = Clock(ned=(1.0, 2.0, -10.0), quaternion=(0.0, 0.0, 0.0, 1.0))
    source = PoseSource(clock, VideoConfig(stale_after_s=0.5))
    now = clock.state.updated_at
    a, b = source.sample(now), source.sample(now + 0.01)
    assert a != b  # never two identical poses while fresh: no false "tracking lost"
    assert a is not None and math.dist(a[0], (1.0, 2.0, -10.0)) < 0.01
    stale = source.sample(now + 0.6)
    assert stale == b and source.sample(now + 0.7) == b
    assert source.stale_samples == 2


def test_between_position_updates_the_pose_is_dead_reckoned_in_simulated_time():
    clock = Clock(ned=(0.0, 0.0, -10.0), velocity_ned=(2.0, 0.0, 0.0), quaternion=(0, 0, 0, 1))
    source = PoseSource(clock, VideoConfig(time_scale=4.0, jitter_m=0.0, jitter_deg=0.0))
    now = clock.state.updated_at
    source.sample(now)
    clock.state = clock.state.with_changes(updated_at=now + 0.1)
    (n, e, d), _ = source.sample(now + 0.1)  # type: ignore[misc]
    assert (n, e, d) == pytest.approx((0.8, 0.0, -10.0))  # 0.1 s real = 0.4 s simulated


def test_the_orientation_comes_from_euler_angles_without_a_quaternion():
    clock = Clock(ned=(0.0, 0.0, -5.0), roll=0.0, pitch=0.0, yaw=90.0)
    source = PoseSource(clock, VideoConfig(jitter_m=0.0, jitter_deg=0.0))
    _, q = source.sample()  # type: ignore[misc]
    assert math.degrees(heading_of(q)) == pytest.approx(90.0)


def test_a_captured_frame_is_a_decodable_jpeg_with_its_pose():
    sent: list[tuple[str, object]] = []
    clock = Clock(ned=(3.0, 4.0, -10.0), quaternion=(0.0, 0.0, 0.0, 1.0))
    streamer = VideoStreamer(clock, lambda ch, m: sent.append((ch, m)), VideoConfig())
    frame = streamer.capture()
    assert frame is not None and sent == [("camera", frame)]
    message = protocol.parse_camera_frame(frame.to_dict())
    assert math.dist(message.position, (3.0, 4.0, -10.0)) < 0.01
    with Image.open(io.BytesIO(message.jpeg)) as image:
        assert image.size == (320, 240)


def test_the_streamer_downsamples_the_camera_and_batches_poses():
    sent: list[tuple[str, object]] = []
    lock = threading.Lock()

    def send(channel: str, message: object) -> None:
        with lock:
            sent.append((channel, message))

    clock = Clock(ned=(0.0, 0.0, -10.0), quaternion=(0.0, 0.0, 0.0, 1.0))
    config = VideoConfig(rate_hz=10.0, pose_hz=100.0, stale_after_s=60.0)
    streamer = VideoStreamer(
        clock, send, config, renderer=lambda position, orientation: b"\xff\xd8\xff\xd9"
    )

    def enough() -> bool:
        with lock:
            frames = sum(1 for channel, _ in sent if channel == "camera")
            poses = sum(len(m.objects) for c, m in sent if c == "telemetry")  # type: ignore[attr-defined]
        return frames >= 5 and poses >= 40

    started = time.monotonic()
    streamer.start()
    # Half a second on a quiet machine; a loaded one takes longer (late ticks are skipped).
    assert wait_for(enough, 10)
    streamer.stop()
    elapsed = time.monotonic() - started
    frames = [m for c, m in sent if c == "camera"]
    batches = [m for c, m in sent if c == "telemetry"]
    # 10 of the camera's 30 frames a second and 100 poses a second, never more.
    assert len(frames) <= elapsed * config.rate_hz + 1
    poses = [o for b in batches for o in b.objects]  # type: ignore[attr-defined]
    assert all(o.name == POSE_OBJECT for o in poses)
    assert len(poses) <= elapsed * config.pose_hz + 1
    # In batches, one every batch_s (and the rest at the stop), not one message per sample.
    assert len(batches) <= elapsed / config.batch_s + 2


def test_a_disabled_streamer_sends_nothing():
    sent: list[object] = []
    clock = Clock(ned=(0.0, 0.0, -10.0), quaternion=(0.0, 0.0, 0.0, 1.0))
    streamer = VideoStreamer(
        clock, lambda c, m: sent.append(m), VideoConfig(rate_hz=30.0), enabled=lambda: False
    )
    streamer.start()
    time.sleep(0.2)
    streamer.stop()
    assert sent == []


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"rate_hz": 60.0}, "rate_hz"),
        ({"pose_hz": 500.0}, "pose_hz"),
        ({"source_hz": 0.0}, "source_hz"),
        ({"batch_s": 0.0}, "batch_s"),
    ],
)
def test_impossible_rates_are_refused(changes, words):
    with pytest.raises(ValueError, match=words):
        VideoConfig(**changes)


def test_the_default_video_keeps_every_fifteenth_frame():
    assert VideoConfig().frame_every == 15


def test_forward_is_north_when_the_drone_faces_north():
    assert commands_for(Stick(1.0, 0.0, 0.0), 0.0, 0.5) == [("changeN", 0.5)]


def test_forward_is_east_and_right_is_south_when_the_drone_faces_east():
    east = math.radians(90.0)
    assert commands_for(Stick(1.0, 0.0, 0.0), east, 0.5) == [("changeE", 0.5)]
    assert commands_for(Stick(0.0, 1.0, 0.0), east, 0.5) == [("changeN", -0.5)]


def test_a_diagonal_is_no_longer_than_a_straight_step_and_up_climbs():
    moves = dict(commands_for(Stick(1.0, 1.0, -1.0), 0.0, 0.5))
    assert math.hypot(moves["changeN"], moves["changeE"]) == pytest.approx(0.5, abs=1e-3)
    assert moves["altitude"] == -0.5


def test_tiny_deflections_send_nothing():
    assert commands_for(Stick(0.01, 0.0, 0.0), 0.0, 0.5) == []


@pytest.mark.parametrize(
    "data", [{"forward": float("nan")}, {"right": 1.5}, {"up": True}, {"forward": "1"}, []]
)
def test_bad_stick_input_is_refused(data):
    with pytest.raises(BadInput):
        Stick.parse(data)

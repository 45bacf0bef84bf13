"""Camera frames and the pose stream for the ground's past-image view (SPIRIT).

Two loops, both on the wall clock:

- video: the camera runs at ``source_hz`` (30 Hz) and every ``source_hz / rate_hz``-th
  frame (2 Hz by default, the rate [Nassar 2017] downsampled its 30 Hz video to)
  is published on ``<id>/camera/out`` with the pose at capture (docs/protocol.md "Camera
  frame"). Frames that would be dropped are never rendered.
- pose: ``pose_hz`` samples a second (up to 200) go out as telemetry objects named
  ``Pose`` on ``<id>/telemetry/out``, batched every ``batch_s``; fields ``North``, ``East``,
  ``Down`` (m) and ``qx``, ``qy``, ``qz``, ``qw`` (body to NED). The telemetry message is
  the contract's generic carrier for flight data, so no new topic is needed.

The simulated pose source behaves like a motion-capture tracker: the flight
controller's estimate (position dead-reckoned with the velocity between the 1 Hz
PositionActual updates) with sub-millimetre jitter, and, when the estimate goes stale,
the last pose repeated unchanged -- which the ground reads as "tracking lost" (two poses
identical but for their time stamp).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

try:
    import numpy as np
except ImportError as exc:  # the package's optional `camera` extra
    raise ImportError(
        "Video and pose streaming need numpy: pip install 'skyhive-onboard[camera]'"
    ) from exc

from . import protocol
from .fc.base import VehicleState

log = logging.getLogger(__name__)

POSE_OBJECT = "Pose"
MAX_POSE_HZ = 200.0

Pose = tuple[tuple[float, float, float], tuple[float, float, float, float]]
Renderer = Callable[[tuple[float, float, float], tuple[float, float, float, float]], bytes]


@dataclass(frozen=True)
class VideoConfig:
    source_hz: float = 30.0
    rate_hz: float = 2.0  # frames published per second; 30 Hz -> 2 Hz by default
    pose_hz: float = 50.0  # pose samples per second; 0 turns the stream off
    batch_s: float = 0.05  # pose samples are sent in one telemetry message this often
    time_scale: float = 1.0  # simulation speed-up: velocities are per simulated second
    stale_after_s: float = 1.0  # no flight-controller object this long: the pose is stale
    max_extrapolation_s: float = 1.5  # simulated seconds of dead reckoning at most
    jitter_m: float = 0.0005  # the simulated motion capture's noise (0 for a real source)
    jitter_deg: float = 0.02
    width: int = 320
    height: int = 240
    quality: int = 70
    seed: int = 2016

    def __post_init__(self) -> None:
        if not 0 < self.source_hz <= 240:
            raise ValueError(f"source_hz must be within (0, 240], got {self.source_hz}")
        if not 0 <= self.rate_hz <= self.source_hz:
            raise ValueError(
                f"rate_hz must be within 0..source_hz ({self.source_hz}), got {self.rate_hz}"
            )
        if not 0 <= self.pose_hz <= MAX_POSE_HZ:
            raise ValueError(f"pose_hz must be within 0..{MAX_POSE_HZ:g}, got {self.pose_hz}")
        for name in ("batch_s", "time_scale", "stale_after_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")

    @property
    def frame_every(self) -> int:
        """Publish every n-th camera frame (15 for 30 Hz -> 2 Hz)."""
        return max(1, round(self.source_hz / self.rate_hz)) if self.rate_hz > 0 else 0


def orientation_of(state: VehicleState) -> tuple[float, float, float, float] | None:
    """Body-to-NED quaternion (qx, qy, qz, qw) of the state, from Euler angles if need be."""
    if state.quaternion is not None:
        return state.quaternion
    if state.roll is None or state.pitch is None or state.yaw is None:
        return None
    cr, sr = math.cos(math.radians(state.roll) / 2), math.sin(math.radians(state.roll) / 2)
    cp, sp = math.cos(math.radians(state.pitch) / 2), math.sin(math.radians(state.pitch) / 2)
    cy, sy = math.cos(math.radians(state.yaw) / 2), math.sin(math.radians(state.yaw) / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


class PoseSource:
    """The drone's pose now, from the flight controller's state, as motion capture gives it.

    ``sample`` returns None until the state has a position and an attitude.
    """

    def __init__(self, state: Callable[[], VehicleState], config: VideoConfig) -> None:
        self._state = state
        self.config = config
        self._rng = np.random.default_rng(config.seed)
        self._ned: tuple[float, float, float] | None = None
        self._ned_at = 0.0
        self._last: Pose | None = None
        self._lock = threading.Lock()
        self.stale_samples = 0

    def sample(self, now: float | None = None) -> Pose | None:
        now = time.monotonic() if now is None else now
        state = self._state()
        with self._lock:
            if state.ned is None:
                return None
            orientation = orientation_of(state)
            if orientation is None:
                return None
            if state.ned != self._ned:
                self._ned, self._ned_at = state.ned, now
            if self._last is not None and now - state.updated_at > self.config.stale_after_s:
                # A lost tracker resends the last pose: the ground reads that as tracking lost.
                self.stale_samples += 1
                return self._last
            pose = (self._extrapolate(state, now), self._jitter(orientation))
            self._last = pose
            return pose

    def _extrapolate(self, state: VehicleState, now: float) -> tuple[float, float, float]:
        assert self._ned is not None
        n, e, d = self._ned
        if state.velocity_ned is not None:
            dt = min((now - self._ned_at) * self.config.time_scale, self.config.max_extrapolation_s)
            vn, ve, vd = state.velocity_ned
            n, e, d = n + vn * dt, e + ve * dt, d + vd * dt
        sigma = self.config.jitter_m
        if sigma > 0:
            dn, de, dd = self._rng.normal(0.0, sigma, 3).tolist()
            n, e, d = n + dn, e + de, d + dd
        return (n, e, d)

    def _jitter(self, q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        sigma = math.radians(self.config.jitter_deg)
        if sigma <= 0:
            return q
        # A small rotation about a random axis, applied on the body side.
        rx, ry, rz = (self._rng.normal(0.0, sigma, 3) / 2).tolist()
        x, y, z, w = q
        out = (
            w * rx + x + y * rz - z * ry,
            w * ry + y + z * rx - x * rz,
            w * rz + z + x * ry - y * rx,
            w - x * rx - y * ry - z * rz,
        )
        norm = math.sqrt(sum(c * c for c in out))
        return (out[0] / norm, out[1] / norm, out[2] / norm, out[3] / norm)


def _sim_renderer(config: VideoConfig) -> Renderer:
    from .synthetic_camera import render_view

    def render(
        position: tuple[float, float, float], orientation: tuple[float, float, float, float]
    ) -> bytes:
        return render_view(
            position,
            orientation,
            width=config.width,
            height=config.height,
            quality=config.quality,
        )

    return render


class VideoStreamer:
    """Publishes camera frames and pose samples while ``enabled()`` (the drone has a camera)."""

    def __init__(
        self,
        state: Callable[[], VehicleState],
        send: Callable[[str, Any], None],
        config: VideoConfig | None = None,
        *,
        enabled: Callable[[], bool] = lambda: True,
        renderer: Renderer | None = None,
    ) -> None:
        self.config = config or VideoConfig()
        self.send = send
        self.enabled = enabled
        self.poses = PoseSource(state, self.config)
        self._renderer = renderer
        self.sent: Counter[str] = Counter()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._pending: list[protocol.TelemetryObject] = []

    def start(self) -> None:
        loops = []
        if self.config.rate_hz > 0:
            loops.append((self._video_loop, "video"))
        if self.config.pose_hz > 0:
            loops.append((self._pose_loop, "pose"))
        for target, name in loops:
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(2)

    # -- video ------------------------------------------------------------------------------

    def capture(self) -> protocol.CameraFrame | None:
        """Render and publish one frame now; None when there is no pose yet or it failed."""
        pose = self.poses.sample()
        if pose is None:
            self.sent["frames_without_pose"] += 1
            return None
        if self._renderer is None:
            self._renderer = _sim_renderer(self.config)
        position, orientation = pose
        try:
            jpeg = self._renderer(position, orientation)
        except (ValueError, OSError) as exc:
            self.sent["frames_failed"] += 1
            log.warning("camera frame not rendered: %s", exc)
            return None
        frame = protocol.CameraFrame(position, orientation, jpeg, ts=time.time())
        self.send("camera", frame)
        self.sent["frames"] += 1
        return frame

    def _video_loop(self) -> None:
        period = 1.0 / self.config.source_hz
        every = self.config.frame_every
        tick = 0
        next_at = time.monotonic()
        while not self._stop.wait(max(0.0, next_at - time.monotonic())):
            next_at += period
            if next_at < time.monotonic():  # fell behind (slow render): skip, do not burst
                next_at = time.monotonic() + period
            tick += 1
            if tick % every or not self.enabled():
                continue
            try:
                self.capture()
            except Exception:  # noqa: BLE001 - the camera must not take the agent down
                self.sent["frames_failed"] += 1
                log.exception("camera frame failed")

    # -- pose -------------------------------------------------------------------------------

    def _pose_loop(self) -> None:
        period = 1.0 / self.config.pose_hz
        next_at = time.monotonic()
        flush_at = next_at + self.config.batch_s
        while not self._stop.wait(max(0.0, next_at - time.monotonic())):
            now = time.monotonic()
            next_at += period
            if next_at < now:
                next_at = now + period
            try:
                if self.enabled():
                    self._sample(now)
                if now >= flush_at:
                    flush_at = now + self.config.batch_s
                    self.flush_poses()
            except Exception:  # noqa: BLE001
                self.sent["poses_failed"] += 1
                log.exception("pose sample failed")
        self.flush_poses()

    def _sample(self, now: float) -> None:
        pose = self.poses.sample(now)
        if pose is None:
            return
        (n, e, d), (qx, qy, qz, qw) = pose
        fields = {"North": n, "East": e, "Down": d, "qx": qx, "qy": qy, "qz": qz, "qw": qw}
        self._pending.append(protocol.TelemetryObject(POSE_OBJECT, time.time(), fields))

    def flush_poses(self) -> None:
        batch, self._pending = self._pending, []
        if batch:
            self.send("telemetry", protocol.Telemetry(tuple(batch)))
            self.sent["poses"] += len(batch)

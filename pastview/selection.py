"""Selection service for one drone: stored frames in, the best past view out, per pose.

``PastView`` downsamples the incoming video (30 Hz -> 2 Hz by default, as [Nassar 2017]
did to simulate line-of-sight conditions), stores frames in a ``FrameBuffer``, tracks the pose
stream, and for each new pose picks the lowest-scoring frame under the configured
evaluation function. It returns plain dicts ready for the page and sends a frame's JPEG
only when the choice changes. No Django, no MQTT: the consumer that feeds it owns I/O.
"""

from __future__ import annotations

import base64
import binascii
import logging
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, TypedDict

import numpy as np

from pastview.buffer import Frame, FrameBuffer, Outcome, is_valid_jpeg
from pastview.evaluation import EvaluationFunction, Spirit, evaluation_from_dict
from pastview.geometry import (
    InvalidPose,
    Pose,
    relative_orientation,
    relative_position,
)
from pastview.tracking import PoseTracker, Transition

log = logging.getLogger(__name__)

# Frame time stamps this close to the downsampling period still count as on time, so
# exact 30 Hz stamps keep every 15th frame despite floating-point error.
PERIOD_SLACK_S = 1e-3


@dataclass(frozen=True)
class PastViewSettings:
    """Per-drone settings; defaults from [Nassar 2017]."""

    capacity: int = 30
    min_distance_m: float = 0.25
    min_yaw_deg: float = 10.0
    video_hz: float = 2.0  # frames kept per second of video; 0 keeps every frame
    store_while_lost: bool = False  # frames are stored only while the pose is tracked
    evaluation: EvaluationFunction = field(default_factory=Spirit)

    def __post_init__(self) -> None:
        if isinstance(self.capacity, bool) or not isinstance(self.capacity, int):
            raise ValueError(f"capacity must be an integer, got {self.capacity!r}")
        if not 1 <= self.capacity <= 100_000:
            raise ValueError(f"capacity must be within 1..100000, got {self.capacity}")
        for name in ("min_distance_m", "min_yaw_deg", "video_hz"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not 0 <= value < float("inf"):
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
        if not isinstance(self.evaluation, EvaluationFunction):
            raise ValueError("evaluation must be an evaluation function")

    def to_dict(self) -> dict[str, Any]:
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data["evaluation"] = self.evaluation.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PastViewSettings:
        """Settings from a dict such as ``to_dict`` makes; missing keys take defaults."""
        if not isinstance(data, dict):
            raise ValueError(f"settings must be an object, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown setting(s): {', '.join(unknown)}")
        values = dict(data)
        if "evaluation" in values:
            values["evaluation"] = evaluation_from_dict(values["evaluation"])
        return cls(**values)


class FrameInfo(TypedDict):
    id: int
    ts: float
    pose: dict[str, list[float]]
    score: float | None  # None when kept without re-evaluation (tracking lost)


class RelativePose(TypedDict):
    position: list[float]
    orientation: list[float]


class Update(TypedDict):
    """What the page gets for one pose."""

    ts: float
    tracking: str  # "tracked" or "lost"
    event: str | None  # "lost" or "found" on a transition
    pose: dict[str, list[float]]
    function: str
    frame: FrameInfo | None  # None until a frame is stored
    changed: bool  # the chosen frame differs from the previous update's
    jpeg: str | None  # base64 JPEG, only when changed
    relative: RelativePose | None  # the drone in the chosen frame's reference


@dataclass
class ServiceStats:
    frames_received: int = 0
    frames_malformed: int = 0
    frames_out_of_order: int = 0
    frames_downsampled: int = 0
    frames_untracked: int = 0
    poses_received: int = 0
    poses_bad: int = 0
    poses_out_of_order: int = 0
    quaternions_repaired: int = 0


class PastView:
    """Past-image view of one drone; feed it frames and poses in arrival order."""

    def __init__(self, settings: PastViewSettings | None = None) -> None:
        self.settings = settings or PastViewSettings()
        self.buffer = FrameBuffer(
            capacity=self.settings.capacity,
            min_distance_m=self.settings.min_distance_m,
            min_yaw_deg=self.settings.min_yaw_deg,
        )
        self.tracker = PoseTracker()
        self.stats = ServiceStats()
        self._last_frame_ts: float | None = None
        self._last_kept_ts: float | None = None
        self._last_pose: Pose | None = None
        self._current: Frame | None = None
        self._live: dict[str, Any] | None = None

    # Frames --------------------------------------------------------------------------

    def add_frame(self, msg: object) -> bool:
        """Take one camera message (docs/protocol.md); True when it was stored in the buffer.

        Malformed, out-of-order, downsampled-away and (while tracking is lost) untracked
        frames are counted in ``stats``; the buffer counts its own drops.
        """
        self.stats.frames_received += 1
        try:
            ts, position, orientation, jpeg_b64 = _parse_frame(msg)
            jpeg = base64.b64decode(jpeg_b64, validate=True)
        except (ValueError, TypeError, KeyError, binascii.Error) as exc:
            self.stats.frames_malformed += 1
            log.info("camera frame dropped: %s", exc)
            return False
        if self._last_frame_ts is not None and ts < self._last_frame_ts:
            self.stats.frames_out_of_order += 1
            log.info("camera frame dropped: %s is older than %s", ts, self._last_frame_ts)
            return False
        self._last_frame_ts = ts
        if not self._due(ts):
            self.stats.frames_downsampled += 1
            return False
        self._last_kept_ts = ts
        if is_valid_jpeg(jpeg, decode=False):  # the buffer decodes the ones it keeps
            self._live = {"ts": ts, "jpeg": jpeg_b64}
        if not self.tracker.tracked and self._last_pose is not None:
            if not self.settings.store_while_lost:
                self.stats.frames_untracked += 1
                return False
        return self.buffer.add(ts, position, orientation, jpeg) is Outcome.STORED

    def _due(self, ts: float) -> bool:
        if self.settings.video_hz <= 0 or self._last_kept_ts is None:
            return True
        return ts - self._last_kept_ts >= 1.0 / self.settings.video_hz - PERIOD_SLACK_S

    def live_frame(self) -> dict[str, Any] | None:
        """The latest downsampled frame, ``{"ts", "jpeg"}`` (base64), for the live view."""
        return self._live

    # Poses ---------------------------------------------------------------------------

    def update_pose(self, ts: object, position: object, orientation: object) -> Update | None:
        """Take one drone pose; the update for the page, or None when the pose is unusable."""
        self.stats.poses_received += 1
        try:
            pose, repaired = Pose.parse(ts, position, orientation)
        except InvalidPose as exc:
            self.stats.poses_bad += 1
            # Poses come at up to 200 Hz: the counter tells how many, the log only samples.
            if self.stats.poses_bad % 1000 == 1:
                log.info("pose dropped (%d so far): %s", self.stats.poses_bad, exc)
            return None
        if self._last_pose is not None and pose.ts < self._last_pose.ts:
            self.stats.poses_out_of_order += 1
            return None
        if repaired:
            self.stats.quaternions_repaired += 1
        self._last_pose = pose
        transition = self.tracker.update(pose.position, pose.orientation)

        previous = self._current
        score: float | None = None
        # While tracking is lost the pose is stale: keep the displayed frame.
        if self.tracker.tracked and len(self.buffer):
            frames = self.buffer.frames()
            current_pose = previous.pose if previous is not None else None
            index, score = self.settings.evaluation.select(frames, pose, current_pose)
            self._current = self.buffer.frame_at(index)
        chosen = self._current
        changed = chosen is not None and (previous is None or previous.id != chosen.id)
        return {
            "ts": pose.ts,
            "tracking": "tracked" if self.tracker.tracked else "lost",
            "event": transition.value if isinstance(transition, Transition) else None,
            "pose": pose.to_dict(),
            "function": self.settings.evaluation.name,
            "frame": _frame_info(chosen, score) if chosen is not None else None,
            "changed": changed,
            "jpeg": base64.b64encode(chosen.jpeg).decode("ascii") if changed and chosen else None,
            "relative": _relative(chosen, pose) if chosen is not None else None,
        }

    # Settings and state --------------------------------------------------------------

    def set_evaluation(self, evaluation: EvaluationFunction) -> None:
        """Switch the evaluation function or its coefficients; takes effect on the next pose."""
        self.settings = replace(self.settings, evaluation=evaluation)

    def status(self) -> dict[str, Any]:
        """Counters and state for the page and logs."""
        return {
            "frames_stored": len(self.buffer),
            "tracking": "tracked" if self.tracker.tracked else "lost",
            "current_frame": self._current.id if self._current else None,
            **asdict(self.stats),
            "buffer": self.buffer.stats.to_dict(),
        }


def _parse_frame(msg: object) -> tuple[float, Any, Any, str]:
    if not isinstance(msg, dict):
        raise ValueError(f"camera message must be an object, got {type(msg).__name__}")
    pose = msg["pose"]
    if not isinstance(pose, dict):
        raise ValueError("pose must be an object")
    ts = float(msg["ts"])
    if not np.isfinite(ts):
        raise ValueError("ts is not finite")
    jpeg = msg["jpeg"]
    if not isinstance(jpeg, str):
        raise ValueError("jpeg must be a base64 string")
    return ts, pose["position"], pose["orientation"], jpeg


def _frame_info(frame: Frame, score: float | None) -> FrameInfo:
    return {
        "id": frame.id,
        "ts": frame.pose.ts,
        "pose": frame.pose.to_dict(),
        "score": score,
    }


def _relative(frame: Frame, pose: Pose) -> RelativePose:
    return {
        "position": relative_position(
            frame.pose.position, frame.pose.orientation, pose.position
        ).tolist(),
        "orientation": relative_orientation(frame.pose.orientation, pose.orientation).tolist(),
    }

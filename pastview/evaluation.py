"""Frame evaluation functions of the past-image view: score every stored frame against a pose.

Each function is a frozen dataclass holding its coefficients and reference values (the
SPIRIT defaults are those of [Nassar 2017]), serialisable to and from a dict for settings
and the page. The lowest score wins. All frames are scored at once with numpy;
``spirit_scores_loop`` is the straightforward per-frame version, kept as the benchmark
baseline and a test oracle.

Frame poses are those of the drone at capture; the camera looks along the body's forward
axis, tilted down by ``camera_pitch_down_deg``. Angles in the scores are radians.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

import numpy as np

from pastview.geometry import Pose, conjugate, rotation_matrices


def left_matrix(q: np.ndarray) -> np.ndarray:
    """Matrix L(q) with L(q) @ b == q * b, for (4,) -> (4, 4) or (N, 4) -> (N, 4, 4)."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        # One quaternion per pose evaluation: plain floats beat stacking 16 tiny arrays.
        x, y, z, w = q.tolist()
        return np.array([[w, -z, y, x], [z, w, -x, y], [-y, x, w, z], [-x, -y, -z, w]])
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([w, -z, y, x], axis=-1),
            np.stack([z, w, -x, y], axis=-1),
            np.stack([-y, x, w, z], axis=-1),
            np.stack([-x, -y, -z, w], axis=-1),
        ],
        axis=-2,
    )


def _yaw_of(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True, slots=True)
class FrameSet:
    """Poses of stored frames in chronological order, with per-frame precomputations.

    ``inverse_rotations`` (N, 3, 3) and ``anchors`` (N, 3) give the drone's position in
    each frame's reference as ``inverse_rotations @ p - anchors``; ``inverse_left`` (N, 4, 4)
    gives its relative orientation as ``inverse_left @ q``. Computing them once per stored
    frame turns a per-pose evaluation into a few matrix products.
    """

    ids: np.ndarray
    timestamps: np.ndarray
    positions: np.ndarray
    orientations: np.ndarray
    inverse_rotations: np.ndarray
    anchors: np.ndarray
    inverse_left: np.ndarray

    @staticmethod
    def derive(positions: np.ndarray, orientations: np.ndarray) -> tuple[np.ndarray, ...]:
        """(inverse_rotations, anchors, inverse_left) of frames with unit orientations."""
        inverse = np.swapaxes(rotation_matrices(orientations), -1, -2)
        anchors = np.einsum("...ij,...j->...i", inverse, positions)
        return inverse, anchors, left_matrix(conjugate(orientations))

    @classmethod
    def from_arrays(
        cls,
        timestamps: np.ndarray,
        positions: np.ndarray,
        orientations: np.ndarray,
        ids: np.ndarray | None = None,
    ) -> FrameSet:
        """FrameSet of arrays (N,), (N, 3) and unit quaternions (N, 4), time-ordered."""
        timestamps = np.ascontiguousarray(timestamps, dtype=float)
        positions = np.ascontiguousarray(positions, dtype=float)
        orientations = np.ascontiguousarray(orientations, dtype=float)
        if ids is None:
            ids = np.arange(len(timestamps), dtype=np.int64)
        return cls(ids, timestamps, positions, orientations, *cls.derive(positions, orientations))

    def __len__(self) -> int:
        return len(self.timestamps)

    def relative_positions(self, position: np.ndarray) -> np.ndarray:
        """The drone's position in every frame's reference, (N, 3)."""
        n = len(self.timestamps)
        return (self.inverse_rotations.reshape(3 * n, 3) @ position).reshape(n, 3) - self.anchors

    def relative_orientations(self, orientation: np.ndarray) -> np.ndarray:
        """The drone's orientation in every frame's reference, (N, 4)."""
        n = len(self.timestamps)
        return (self.inverse_left.reshape(4 * n, 4) @ orientation).reshape(n, 4)


def _check_parameters(obj: EvaluationFunction) -> None:
    """Refuse non-numbers, NaN and out-of-range values; store every value as a float."""
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{f.name} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{f.name} must be finite, got {value!r}")
        if f.name in obj.POSITIVE and value <= 0:
            raise ValueError(f"{f.name} must be positive, got {value!r}")
        if (f.name.startswith("coeff_") or f.name in obj.NON_NEGATIVE) and value < 0:
            # A negative weight would reward the very thing its term penalises.
            raise ValueError(f"{f.name} must not be negative, got {value!r}")
        object.__setattr__(obj, f.name, float(value))


class EvaluationFunction:
    """Common interface: ``scores`` for every frame, ``select`` the best one."""

    name: ClassVar[str]
    POSITIVE: ClassVar[frozenset[str]] = frozenset()
    NON_NEGATIVE: ClassVar[frozenset[str]] = frozenset()

    def __post_init__(self) -> None:
        _check_parameters(self)

    def scores(self, frames: FrameSet, pose: Pose, current: Pose | None = None) -> np.ndarray:
        raise NotImplementedError

    def select(
        self, frames: FrameSet, pose: Pose, current: Pose | None = None
    ) -> tuple[int, float]:
        """Index and score of the lowest-scoring frame; ``frames`` must not be empty."""
        scores = self.scores(frames, pose, current)
        index = int(np.argmin(scores))
        return index, float(scores[index])

    def to_dict(self) -> dict[str, Any]:
        return {"function": self.name, **asdict(self)}  # type: ignore[call-overload]


@dataclass(frozen=True, slots=True)
class ConstantTimeDelay(EvaluationFunction):
    """[Shiroma 2004]: the frame whose age is closest to ``ref_delay_s``."""

    name: ClassVar[str] = "constant_time_delay"
    NON_NEGATIVE: ClassVar[frozenset[str]] = frozenset({"ref_delay_s"})
    ref_delay_s: float = 2.0  # our default: 4 frames at 2 Hz

    def scores(self, frames: FrameSet, pose: Pose, current: Pose | None = None) -> np.ndarray:
        return np.abs(frames.timestamps - (pose.ts - self.ref_delay_s))

    def select(
        self, frames: FrameSet, pose: Pose, current: Pose | None = None
    ) -> tuple[int, float]:
        # Frames are chronological: a binary search, not a scan.
        target = pose.ts - self.ref_delay_s
        ts = frames.timestamps
        right = int(np.searchsorted(ts, target))
        if right == 0:
            index = 0
        elif right == len(ts):
            index = right - 1
        else:
            index = right if ts[right] - target < target - ts[right - 1] else right - 1
        return index, abs(float(ts[index]) - target)


@dataclass(frozen=True, slots=True)
class ConstantDistance(EvaluationFunction):
    """[Shiroma 2004]: the frame whose distance to the drone is closest to the reference."""

    name: ClassVar[str] = "constant_distance"
    POSITIVE: ClassVar[frozenset[str]] = frozenset({"ref_distance"})
    ref_distance: float = 2.5

    def scores(self, frames: FrameSet, pose: Pose, current: Pose | None = None) -> np.ndarray:
        offsets = frames.positions - pose.position
        return np.abs(np.sqrt(np.einsum("ij,ij->i", offsets, offsets)) - self.ref_distance)


@dataclass(frozen=True, slots=True)
class Murata(EvaluationFunction):
    """[Murata 2014] (3D): height of the viewpoint above the drone, azimuth, tilt, distance.

    E = a1 ((h - h_ref)/h_ref)^2 + a2 beta^2 + a3 (alpha - alpha_ref)^2
        + a4 ((|d| - l_ref)/l_ref)^2
    with h the viewpoint's height above the drone, beta the yaw of the drone relative to
    the frame (azimuth), alpha the tilt (depression angle from the viewpoint down to the
    drone) and d the offset between them. The terms are those of [Murata 2014]; unit
    coefficients, 1 m height and a tilt consistent with it at 2.5 m are our defaults.
    """

    name: ClassVar[str] = "murata"
    POSITIVE: ClassVar[frozenset[str]] = frozenset({"ref_height", "ref_distance"})
    coeff_height: float = 1.0
    coeff_azimuth: float = 1.0
    coeff_tilt: float = 1.0
    coeff_distance: float = 1.0
    ref_height: float = 1.0
    ref_tilt_deg: float = 23.6  # asin(1 / 2.5): looking down at the drone from 1 m above
    ref_distance: float = 2.5

    def scores(self, frames: FrameSet, pose: Pose, current: Pose | None = None) -> np.ndarray:
        offsets = pose.position - frames.positions
        height = offsets[:, 2]  # NED: the viewpoint is above when the drone's d is larger
        horizontal = np.hypot(offsets[:, 0], offsets[:, 1])
        distance = np.hypot(horizontal, height)
        tilt = np.arctan2(height, horizontal)
        azimuth = _yaw_of(frames.relative_orientations(pose.orientation))
        return (
            self.coeff_height * ((height - self.ref_height) / self.ref_height) ** 2
            + self.coeff_azimuth * azimuth**2
            + self.coeff_tilt * (tilt - math.radians(self.ref_tilt_deg)) ** 2
            + self.coeff_distance * ((distance - self.ref_distance) / self.ref_distance) ** 2
        )


@dataclass(frozen=True, slots=True)
class Spirit(EvaluationFunction):
    """The SPIRIT function of [Nassar 2017], five weighted terms.

    centrality      |drone off the camera axis| / d_ref
    direction       (yaw of the drone relative to the frame)^2
    distance        ((|drone - frame| - d_ref) / d_ref)^2
    direction_with_current  (yaw of the frame relative to the displayed frame)^2
    distance_with_current   |frame - displayed frame| / d_ref
    Centrality uses the two axes across the camera's line of sight (the frame of
    [Nassar 2017] looked along y). A drone behind the camera cannot be in the picture, so there its
    whole distance counts as off-centre.
    The last two terms are zero while no frame is displayed.
    """

    name: ClassVar[str] = "spirit"
    POSITIVE: ClassVar[frozenset[str]] = frozenset({"ref_distance"})
    coeff_centrality: float = 4.0
    coeff_direction: float = 2.0
    coeff_distance: float = 8.0
    coeff_direction_with_current: float = 1.0
    coeff_distance_with_current: float = 2.0
    ref_distance: float = 2.5
    camera_pitch_down_deg: float = 0.0

    def camera_axis(self) -> np.ndarray:
        theta = math.radians(self.camera_pitch_down_deg)
        return np.array([math.cos(theta), 0.0, math.sin(theta)])

    def terms(
        self, frames: FrameSet, pose: Pose, current: Pose | None = None
    ) -> dict[str, np.ndarray]:
        """The five unweighted terms, each (N,)."""
        rel = frames.relative_positions(pose.position)
        squared = np.einsum("ij,ij->i", rel, rel)
        axis = self.camera_axis()
        # The offset from the camera axis (not sqrt(|d|^2 - along^2): that cancels badly).
        across = rel - np.maximum(rel @ axis, 0.0)[:, None] * axis
        lateral = np.sqrt(np.einsum("ij,ij->i", across, across))
        direction = _yaw_of(frames.relative_orientations(pose.orientation))
        terms = {
            "centrality": lateral / self.ref_distance,
            "direction": direction * direction,
            "distance": ((np.sqrt(squared) - self.ref_distance) / self.ref_distance) ** 2,
        }
        if current is None:
            zeros = np.zeros(len(frames))
            terms["direction_with_current"] = zeros
            terms["distance_with_current"] = zeros
        else:
            to_current = frames.orientations @ left_matrix(conjugate(current.orientation)).T
            offsets = frames.positions - current.position
            turn = _yaw_of(to_current)
            terms["direction_with_current"] = turn * turn
            terms["distance_with_current"] = (
                np.sqrt(np.einsum("ij,ij->i", offsets, offsets)) / self.ref_distance
            )
        return terms

    def scores(self, frames: FrameSet, pose: Pose, current: Pose | None = None) -> np.ndarray:
        t = self.terms(frames, pose, current)
        return (
            self.coeff_centrality * t["centrality"]
            + self.coeff_direction * t["direction"]
            + self.coeff_distance * t["distance"]
            + self.coeff_direction_with_current * t["direction_with_current"]
            + self.coeff_distance_with_current * t["distance_with_current"]
        )


FUNCTIONS: dict[str, type[EvaluationFunction]] = {
    f.name: f for f in (ConstantTimeDelay, ConstantDistance, Murata, Spirit)
}


def evaluation_from_dict(data: dict[str, Any]) -> EvaluationFunction:
    """Evaluation function from ``{"function": name, **parameters}``; missing ones default.

    Raises ValueError naming the problem for an unknown function or parameter, or a
    value that is not a finite number in range.
    """
    if not isinstance(data, dict):
        raise ValueError(f"evaluation settings must be an object, got {type(data).__name__}")
    name = data.get("function", Spirit.name)
    cls = FUNCTIONS.get(name)
    if cls is None:
        raise ValueError(f"unknown evaluation function {name!r}; known: {sorted(FUNCTIONS)}")
    allowed = {f.name for f in fields(cls)}  # type: ignore[arg-type]
    params = {k: v for k, v in data.items() if k != "function"}
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise ValueError(f"unknown parameter(s) for {name}: {', '.join(unknown)}")
    return cls(**params)


def _quat_mul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + bw * ax + ay * bz - az * by,
        aw * by + bw * ay + az * bx - ax * bz,
        aw * bz + bw * az + ax * by - ay * bx,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _quat_yaw(q: tuple[float, ...]) -> float:
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def spirit_scores_loop(
    spirit: Spirit,
    positions: list[tuple[float, float, float]],
    orientations: list[tuple[float, float, float, float]],
    pose: Pose,
    current: Pose | None = None,
) -> list[float]:
    """The SPIRIT function one frame at a time in plain Python.

    The benchmark's baseline and the tests' oracle for ``Spirit.scores``.
    """
    ref = spirit.ref_distance
    axis = spirit.camera_axis().tolist()
    px, py, pz = pose.position.tolist()
    q_drone = tuple(pose.orientation.tolist())
    if current is not None:
        cx, cy, cz = current.position.tolist()
        cqx, cqy, cqz, cqw = current.orientation.tolist()
        conj_current = (-cqx, -cqy, -cqz, cqw)
    out = []
    for (fx, fy, fz), (qx, qy, qz, qw) in zip(positions, orientations, strict=True):
        conj_frame = (-qx, -qy, -qz, qw)
        # Rotate the world offset into the frame's reference: q* v q.
        offset = (px - fx, py - fy, pz - fz, 0.0)
        rx, ry, rz, _ = _quat_mul(_quat_mul(conj_frame, offset), (qx, qy, qz, qw))
        distance = math.sqrt(rx * rx + ry * ry + rz * rz)
        along = max(rx * axis[0] + ry * axis[1] + rz * axis[2], 0.0)
        lateral = math.sqrt(
            (rx - along * axis[0]) ** 2 + (ry - along * axis[1]) ** 2 + (rz - along * axis[2]) ** 2
        )
        direction = _quat_yaw(_quat_mul(conj_frame, q_drone))
        score = (
            spirit.coeff_centrality * lateral / ref
            + spirit.coeff_direction * direction * direction
            + spirit.coeff_distance * ((distance - ref) / ref) ** 2
        )
        if current is not None:
            turn = _quat_yaw(_quat_mul(conj_current, (qx, qy, qz, qw)))
            gap = math.sqrt((fx - cx) ** 2 + (fy - cy) ** 2 + (fz - cz) ** 2)
            score += spirit.coeff_direction_with_current * turn * turn
            score += spirit.coeff_distance_with_current * gap / ref
        out.append(score)
    return out

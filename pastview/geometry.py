"""Quaternion and relative-pose helpers, vectorised over arrays of frames.

Conventions: quaternions are ``(qx, qy, qz, qw)`` arrays (the wire order of docs/protocol.md)
rotating body vectors into the world frame; positions are NED metres; the body frame is
forward-right-down, so yaw is the heading from north, clockwise seen from above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# A quaternion whose norm is this far from 1 is renormalised and counted as repaired.
UNIT_TOLERANCE = 1e-6


class InvalidPose(ValueError):
    """A position or orientation that cannot be used (NaN, infinite, zero, wrong shape)."""


def normalise(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) of shape (4,) or (N, 4); NaN, infinity and zero are refused."""
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise InvalidPose(f"a quaternion has 4 components, got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InvalidPose("quaternion has NaN or infinite components")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-9):
        raise InvalidPose("quaternion has zero norm")
    return q / norm


def conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion), (4,) or (N, 4)."""
    return np.asarray(q, dtype=float) * np.array([-1.0, -1.0, -1.0, 1.0])


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a*b (apply b, then a), broadcasting over leading axes."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bx + bw * ax + ay * bz - az * by,
            aw * by + bw * ay + az * bx - ax * bz,
            aw * bz + bw * az + ax * by - ay * bx,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """Body-to-world rotation matrix of unit quaternion(s): (4,) -> (3, 3), (N, 4) -> (N, 3, 3).

    The standard matrix of a unit quaternion (x, y, z, w).
    """
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - z * w)
    m[..., 0, 2] = 2 * (x * z + y * w)
    m[..., 1, 0] = 2 * (x * y + z * w)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - x * w)
    m[..., 2, 0] = 2 * (x * z - y * w)
    m[..., 2, 1] = 2 * (y * z + x * w)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vector(s) v by unit quaternion(s) q (body to world), broadcasting."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u, w = q[..., :3], q[..., 3:4]
    # v' = v + 2w (u x v) + 2 u x (u x v): two cross products instead of a matrix.
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def yaw(q: np.ndarray) -> np.ndarray:
    """Heading angle in radians (-pi..pi] of unit quaternion(s), Z-Y-X Euler convention."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def from_yaw(yaw_rad: float | np.ndarray) -> np.ndarray:
    """Level orientation(s) with the given heading in radians."""
    half = np.asarray(yaw_rad, dtype=float) / 2.0
    zeros = np.zeros_like(half)
    return np.stack([zeros, zeros, np.sin(half), np.cos(half)], axis=-1)


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Angle(s) wrapped into [-pi, pi)."""
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def relative_position(
    frame_positions: np.ndarray, frame_orientations: np.ndarray, position: np.ndarray
) -> np.ndarray:
    """The drone's position in each frame's own reference, (N, 3) or (3,).

    The world offset rotated by the inverse of the frame's orientation.
    """
    offset = np.asarray(position, dtype=float) - np.asarray(frame_positions, dtype=float)
    return rotate(conjugate(frame_orientations), offset)


def relative_orientation(frame_orientations: np.ndarray, orientation: np.ndarray) -> np.ndarray:
    """The drone's orientation in each frame's reference: conj(q_frame) * q_drone.

    The frame's quaternion is inverted so that the result is relative to the frame, as
    the relative position is.
    """
    return multiply(conjugate(frame_orientations), orientation)


@dataclass(frozen=True, slots=True)
class Pose:
    """A time-stamped pose: NED position (3,) and unit quaternion (4,)."""

    ts: float
    position: np.ndarray
    orientation: np.ndarray

    @classmethod
    def parse(cls, ts: object, position: object, orientation: object) -> tuple[Pose, bool]:
        """Validated pose and whether its quaternion had to be renormalised.

        Raises InvalidPose for a non-finite time stamp or position, or a NaN, infinite or
        zero quaternion.
        """
        try:
            stamp = float(ts)  # type: ignore[arg-type]
            p = np.asarray(position, dtype=float)
            q = np.asarray(orientation, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidPose(f"pose is not numeric: {exc}") from exc
        if not math.isfinite(stamp):
            raise InvalidPose("time stamp is not finite")
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidPose(f"position must be 3 finite numbers, got {position!r}")
        if q.shape != (4,):
            raise InvalidPose(f"orientation must be 4 numbers, got {orientation!r}")
        unit = normalise(q)
        repaired = abs(float(np.linalg.norm(q)) - 1.0) > UNIT_TOLERANCE
        p.setflags(write=False)
        unit.setflags(write=False)
        return cls(stamp, p, unit), repaired

    def to_dict(self) -> dict[str, list[float]]:
        """The protocol's pose object: ``{"position": [n, e, d], "orientation": [qx, qy, qz, qw]}``."""
        return {"position": self.position.tolist(), "orientation": self.orientation.tolist()}

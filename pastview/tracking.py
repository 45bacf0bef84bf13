"""Pose tracking: is the pose stream still live?

A tracker that loses the drone keeps sending the last known pose with fresh time stamps.
So tracking counts as lost when two consecutive poses are identical but for their time
stamp, and found again on the next pose that differs. Cheap enough for 200 Hz.
"""

from __future__ import annotations

import enum

import numpy as np


class Transition(enum.Enum):
    LOST = "lost"
    FOUND = "found"


class PoseTracker:
    """Feed every pose in order; ``update`` reports a transition when the state flips."""

    def __init__(self) -> None:
        self._position: np.ndarray | None = None
        self._orientation: np.ndarray | None = None
        self.tracked = False  # nothing seen yet
        self.lost_count = 0

    def update(self, position: np.ndarray, orientation: np.ndarray) -> Transition | None:
        """Record one pose; returns LOST or FOUND when the state changes, else None."""
        position = np.array(position, dtype=float)
        orientation = np.array(orientation, dtype=float)
        last_position, last_orientation = self._position, self._orientation
        self._position, self._orientation = position, orientation
        if last_position is None or last_orientation is None:
            self.tracked = True  # the first pose is news, not a recovery: no transition
            return None
        same = np.array_equal(position, last_position) and np.array_equal(
            orientation, last_orientation
        )
        if same and self.tracked:
            self.tracked = False
            self.lost_count += 1
            return Transition.LOST
        if not same and not self.tracked:
            self.tracked = True
            return Transition.FOUND
        return None

"""The past view: pushes to the page and teleoperation from it."""

from __future__ import annotations

from config.env import env

# Relative poses reach the page at most this often per drone (new frames and tracking
# events are pushed at once); teleoperation moves are rate-limited and bounded per step.
PASTVIEW_PUSH_HZ = env.float("PASTVIEW_PUSH_HZ", 30.0)
PASTVIEW_TELEOP_HZ = env.float("PASTVIEW_TELEOP_HZ", 4.0)
PASTVIEW_TELEOP_STEP_M = env.float("PASTVIEW_TELEOP_STEP_M", 0.5)
# Teleoperation from the past view only while the drone's camera frames and tracked poses
# are this fresh (the page offers it and the server accepts moves on the same rule).
PASTVIEW_TELEOP_FRESH_S = env.float("PASTVIEW_TELEOP_FRESH_S", 3.0)

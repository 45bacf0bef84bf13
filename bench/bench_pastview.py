"""Past-image view: SPIRIT frame selection time per pose, vectorised vs per-frame loop.

[Nassar 2017] scored frames one at a time (up to 0.3 ms each) and lagged from about twenty
frames. Poses arrive at up to 200 Hz, so a selection must take well under 5 ms; the goal
is a 1 000-frame buffer in under 1 ms. Both implementations score the same frames against
the same poses in this run. Run: .venv/bin/python -m bench.bench_pastview
"""

from __future__ import annotations

import time

import numpy as np

from bench.common import best_of, record
from onboard.synthetic_camera import orientation_from_euler, render_view
from pastview.buffer import FrameBuffer, Outcome
from pastview.evaluation import Spirit, spirit_scores_loop
from pastview.geometry import Pose
from pastview.selection import PastView, PastViewSettings

SIZES = (30, 1_000, 10_000)
POSES = 64
GOAL = "1000-frame buffer < 1 ms"


def flight(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A wandering flight: n poses 0.3 m apart with drifting heading and small tilts."""
    headings = np.cumsum(rng.normal(scale=0.15, size=n))
    steps = 0.3 * np.stack([np.cos(headings), np.sin(headings), rng.normal(0, 0.1, n)], axis=1)
    positions = np.cumsum(steps, axis=0) + [0.0, 0.0, -3.0]
    orientations = np.array(
        [
            orientation_from_euler(r, p, np.degrees(h))
            for r, p, h in zip(rng.normal(0, 3, n), rng.normal(0, 3, n), headings, strict=True)
        ]
    )
    return positions, orientations


def filled_buffer(n: int, rng: np.random.Generator) -> FrameBuffer:
    jpeg = render_view((0.0, 0.0, -3.0), (0.0, 0.0, 0.0, 1.0), width=32, height=24)
    buffer = FrameBuffer(capacity=n, decode_jpeg=False)
    positions, orientations = flight(n, rng)
    for i in range(n):
        outcome = buffer.add(float(i) * 0.5, positions[i], orientations[i], jpeg)
        assert outcome is Outcome.STORED, outcome
    return buffer


def bench_size(n: int) -> None:
    spirit = Spirit()
    rng = np.random.default_rng(n)
    buffer = filled_buffer(n, rng)
    frames = buffer.frames()
    positions = frames.positions.tolist()
    orientations = [tuple(q) for q in frames.orientations.tolist()]
    # Poses near the recent end of the flight; the displayed frame is one of the stored.
    poses = [
        Pose(n * 0.5 + i, frames.positions[-1] + rng.normal(0, 1, 3), frames.orientations[-1])
        for i in range(POSES)
    ]
    current = buffer.frame_at(-5).pose
    loop_poses = poses[: max(2, POSES * 30 // n)]

    for pose in poses[:4]:  # the two must agree before either is timed
        index, _ = spirit.select(frames, pose, current)
        loop = spirit_scores_loop(spirit, positions, orientations, pose, current)
        assert index == int(np.argmin(loop)), "vectorised and loop disagree"

    def vectorised() -> None:
        for pose in poses:
            spirit.select(frames, pose, current)

    def per_frame_loop() -> None:
        for pose in loop_poses:
            scores = spirit_scores_loop(spirit, positions, orientations, pose, current)
            min(range(len(scores)), key=scores.__getitem__)

    ours = best_of(vectorised, repeat=7) / len(poses)
    baseline = best_of(per_frame_loop, repeat=3) / len(loop_poses)

    # The whole service step (validation, tracking, selection, reply dict), for context.
    view = PastView(PastViewSettings(capacity=n))
    view.buffer = buffer
    start = time.perf_counter()
    for i, pose in enumerate(poses):
        view.update_pose(pose.ts, pose.position + 0.001 * i, pose.orientation)
    service = (time.perf_counter() - start) / len(poses)

    record(
        f"pastview.select_{n}",
        value=ours,
        unit="s/pose",
        baseline_name="per-frame Python loop of the same SPIRIT function",
        baseline_value=baseline,
        higher_is_better=False,
        goal=GOAL,
        frames=n,
        service_update_pose_s=service,
    )


def main() -> None:
    for n in SIZES:
        bench_size(n)


if __name__ == "__main__":
    main()

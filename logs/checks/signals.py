"""Signal helpers the checks share: runs of a condition, running extremes, and the
vibration metric PX4 computes on board."""

from __future__ import annotations

import numpy as np

# PX4 VehicleIMU::UpdateAccelVibrationMetrics [PX4 VehicleIMU]: the metric is a low-pass
# (0.99 old + 0.01 new) of the length of the change between consecutive accelerations.
PX4_VIBE_ALPHA = 0.01
_EMA_BLOCK = 2048


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a boolean array."""
    if not len(mask):
        return []
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def timed_runs(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) times of the True runs; a run lasts until the next sample after it
    (the state holds until something else is recorded), or its last sample at the end."""
    out = []
    for a, b in runs(mask):
        end = t[b] if b < len(t) else t[b - 1]
        out.append((float(t[a]), float(end)))
    return out


def held(values: np.ndarray, n: int) -> np.ndarray:
    """The running minimum over n consecutive samples (a level held for n records), at
    the last sample of each window; shorter arrays keep their values."""
    if n <= 1 or len(values) < n:
        return values
    windows = np.lib.stride_tricks.sliding_window_view(values, n)
    out = np.empty_like(values)
    out[: n - 1] = values[: n - 1]
    out[n - 1 :] = windows.min(axis=1)
    return out


def ema(x: np.ndarray, alpha: float, start: float = 0.0) -> np.ndarray:
    """y[k] = (1 - alpha) y[k-1] + alpha x[k], vectorised per block: within a block y is
    a weighted cumulative sum, the weights kept within float range by the block length."""
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    keep = 1.0 - alpha
    powers = keep ** np.arange(1, _EMA_BLOCK + 1)
    inverse = keep ** -np.arange(1, _EMA_BLOCK + 1)
    prev = start
    for lo in range(0, len(x), _EMA_BLOCK):
        block = x[lo : lo + _EMA_BLOCK]
        n = len(block)
        acc = np.cumsum(block * inverse[:n]) * alpha
        out[lo : lo + n] = powers[:n] * (prev + acc)
        prev = out[lo + n - 1]
    return out


def px4_accel_vibration(ax: np.ndarray, ay: np.ndarray, az: np.ndarray) -> np.ndarray:
    """PX4's accel_vibration_metric recomputed from logged accelerations (m/s²)."""
    diff = np.sqrt(np.diff(ax) ** 2 + np.diff(ay) ** 2 + np.diff(az) ** 2)
    return np.concatenate([[0.0], ema(diff, PX4_VIBE_ALPHA)])


def first_time(t: np.ndarray, mask: np.ndarray) -> float | None:
    hit = np.flatnonzero(mask)
    return float(t[hit[0]]) if len(hit) else None

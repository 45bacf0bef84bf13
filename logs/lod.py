"""Level-of-detail: few enough points for a plot of a given pixel width, shape preserved.

`minmax` keeps, per pixel-wide time bucket, the sample with the lowest and the one with
the highest value, in time order (at most 2 x points samples): every spike stays visible.
`lttb` (Largest-Triangle-Three-Buckets, Steinarsson 2013) keeps exactly `points` samples
that best preserve the visual shape; it looks smoother but may drop a one-sample spike.
"""

from __future__ import annotations

from typing import Literal

import numpy as np


def downsample(
    t: np.ndarray, v: np.ndarray, points: int, *, method: Literal["minmax", "lttb"] = "minmax"
) -> tuple[np.ndarray, np.ndarray]:
    """Reduce a time-sorted series to about `points` buckets; short series come back as is.

    NaN values are dropped (a plot cannot draw them); text series are returned unchanged.
    """
    if points < 1:
        raise ValueError("points must be at least 1")
    if v.dtype.kind not in "iufb":
        return t, v
    if v.dtype.kind == "f":
        keep = np.isfinite(v)
        if not keep.all():
            t, v = t[keep], v[keep]
    limit = 2 * points if method == "minmax" else points
    if len(t) <= limit:
        return t, v
    idx = _minmax(t, v, points) if method == "minmax" else _lttb(t, v, max(points, 3))
    return t[idx], v[idx]


def _buckets(t: np.ndarray, points: int) -> np.ndarray:
    span = float(t[-1] - t[0]) or 1.0
    # Subtract in the input type first so int64 nanoseconds keep their precision.
    return np.minimum(
        ((t - t[0]).astype(np.float64) * (points / span)).astype(np.int64), points - 1
    )


def _first_per_bucket(candidates: np.ndarray, bucket: np.ndarray) -> np.ndarray:
    b = bucket[candidates]
    first = np.empty(len(b), dtype=bool)
    first[0] = True
    np.not_equal(b[1:], b[:-1], out=first[1:])
    return candidates[first]


def _minmax(t: np.ndarray, v: np.ndarray, points: int) -> np.ndarray:
    bucket = _buckets(t, points)
    starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
    counts = np.diff(np.r_[starts, len(v)])
    vmin = np.repeat(np.minimum.reduceat(v, starts), counts)
    vmax = np.repeat(np.maximum.reduceat(v, starts), counts)
    imin = _first_per_bucket(np.flatnonzero(v == vmin), bucket)
    imax = _first_per_bucket(np.flatnonzero(v == vmax), bucket)
    return np.union1d(imin, imax)  # sorted, so extremes come out in time order


def _lttb(t: np.ndarray, v: np.ndarray, points: int) -> np.ndarray:
    n = len(t)
    x = (t - t[0]).astype(np.float64)
    y = v.astype(np.float64)
    # points - 2 buckets over the samples between the fixed first and last one.
    edges = (np.arange(points - 1) * ((n - 2) / (points - 2))).astype(np.int64) + 1
    edges[-1] = n - 1
    sums_x = np.add.reduceat(x[1 : n - 1], edges[:-1] - 1)
    sums_y = np.add.reduceat(y[1 : n - 1], edges[:-1] - 1)
    sizes = np.diff(edges)
    avg_x = np.r_[sums_x / sizes, x[-1]]
    avg_y = np.r_[sums_y / sizes, y[-1]]
    out = np.empty(points, dtype=np.int64)
    out[0], out[-1] = 0, n - 1
    a = 0
    for i in range(points - 2):
        s, e = edges[i], edges[i + 1]
        # Twice the triangle area of (selected a, candidate, next bucket's average).
        area = np.abs(
            (x[a] - avg_x[i + 1]) * (y[s:e] - y[a]) - (x[a] - x[s:e]) * (avg_y[i + 1] - y[a])
        )
        a = s + int(np.argmax(area))
        out[i + 1] = a
    return out

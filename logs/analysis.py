"""Analyses the viewer runs on a parsed log: estimated trajectory without GPS, attitude
from Euler angles, and every value at a selected time."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from logs.series import LogData, find_special
from logs.store import NS, LogStore

# [Procházka 2016], §5.2.1, trusted intervals under 20 ms for 200 Hz AR.Drone navdata; a default
# that suits 50 Hz streams too. Longer gaps leave the drone where it was.
DEFAULT_MAX_GAP_S = 0.1


@dataclass
class Trajectory:
    """Positions from the start point: x to the north, y to the west ([Procházka 2016], §5.2.1),
    in the velocity's length unit (mm/s in -> mm out)."""

    t: np.ndarray  # seconds
    x: np.ndarray
    y: np.ndarray
    unit: str = ""


def estimate_trajectory(
    t: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    yaw: np.ndarray,
    *,
    max_gap_s: float = DEFAULT_MAX_GAP_S,
) -> Trajectory:
    """Integrate body-frame velocity (x forward, y right) rotated by yaw (radians from north,
    clockwise seen from above) with the trapezoid rule; intervals longer than max_gap_s (or
    not increasing) add no movement."""
    t = np.asarray(t, dtype=np.float64)
    cos, sin = np.cos(yaw), np.sin(yaw)
    north = vx * cos - vy * sin
    east = vx * sin + vy * cos
    dt = np.diff(t)
    valid = (dt > 0) & (dt <= max_gap_s)
    step_n = np.where(valid, (north[1:] + north[:-1]) * 0.5 * dt, 0.0)
    step_e = np.where(valid, (east[1:] + east[:-1]) * 0.5 * dt, 0.0)
    x = np.concatenate([[0.0], np.cumsum(step_n)])
    y = -np.concatenate([[0.0], np.cumsum(step_e)])
    return Trajectory(t, x, y)


def _axis(angle: np.ndarray, axis: int) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {
        0: [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        1: [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        2: [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return np.moveaxis(np.array(rows, dtype=np.float64), (0, 1), (-2, -1))


def rotation_matrix(
    yaw: float | np.ndarray, pitch: float | np.ndarray, roll: float | np.ndarray
) -> np.ndarray:
    """Body-to-world rotation (x forward, y right, z down; radians): first yaw about z, then
    pitch about the new y, then roll about the newest x — the order [Procházka 2016],
    §4.2.1, found experimentally. Arrays give a stack of matrices (..., 3, 3)."""
    yaw, pitch, roll = np.asarray(yaw, float), np.asarray(pitch, float), np.asarray(roll, float)
    return _axis(yaw, 2) @ _axis(pitch, 1) @ _axis(roll, 0)


def quaternion(
    yaw: float | np.ndarray, pitch: float | np.ndarray, roll: float | np.ndarray
) -> np.ndarray:
    """The same rotation as rotation_matrix as a unit quaternion (w, x, y, z) (..., 4)."""
    cy, sy = np.cos(np.asarray(yaw) / 2), np.sin(np.asarray(yaw) / 2)
    cp, sp = np.cos(np.asarray(pitch) / 2), np.sin(np.asarray(pitch) / 2)
    cr, sr = np.cos(np.asarray(roll) / 2), np.sin(np.asarray(roll) / 2)
    return np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )


def _reader(source: LogData | LogStore):
    """(paths, read(path) -> (t_ns, values), labels(path), special) for a log or a store."""
    if isinstance(source, LogStore):
        return source.paths, source.read_ns, lambda p: source.info(p).get("labels"), source.special

    def read(path: str) -> tuple[np.ndarray, np.ndarray]:
        s = source.series[path]
        return s.times, s.values

    def labels(path: str) -> dict[str, str] | None:
        lab = source.series[path].labels
        return {str(k): v for k, v in lab.items()} if lab else None

    return list(source.series), read, labels, find_special(source)


def values_at(source: LogData | LogStore, t: float) -> dict[str, dict | None]:
    """The last sample at or before `t` (seconds) of every series: {path: {"t", "value",
    "label"}} or None where the series has not started yet."""
    paths, read, labels, _ = _reader(source)
    t_ns = math.floor(t * NS)
    out: dict[str, dict | None] = {}
    for path in paths:
        times, values = read(path)
        i = int(np.searchsorted(times, t_ns, side="right")) - 1
        if i < 0:
            out[path] = None
            continue
        value = values[i].item()
        lab = labels(path)
        out[path] = {
            "t": int(times[i]) / NS,
            "value": value,
            "label": lab.get(str(value)) if lab else None,
        }
    return out


def values_tree(flat: dict[str, dict | None]) -> dict:
    """values_at's result nested by path segments, for the tree view."""
    root: dict = {}
    for path, entry in flat.items():
        *groups, name = path.split("/")
        node = root
        for g in groups:
            node = node.setdefault(g, {})
        node[name] = entry
    return root


def _radians(values: np.ndarray, unit: str) -> np.ndarray:
    return (
        np.radians(values)
        if unit.lower() in ("deg", "degree", "degrees", "°")
        else values.astype(np.float64)
    )


def trajectory_of(
    source: LogData | LogStore, *, max_gap_s: float = DEFAULT_MAX_GAP_S
) -> Trajectory | None:
    """The estimated trajectory from the log's special velocity and rotation series, or None
    when the log lacks them. Yaw is interpolated onto the velocity's time stamps."""
    _, read, _, special = _reader(source)
    velocity, rotation = special.get("velocity"), special.get("rotation")
    if not velocity or len(velocity) < 2 or not rotation or len(rotation) < 3:
        return None
    if isinstance(source, LogStore):
        units = {p: source.info(p)["unit"] for p in (velocity[0], rotation[2])}
    else:
        units = {p: source.series[p].unit for p in (velocity[0], rotation[2])}
    t, vx = read(velocity[0])
    _, vy = read(velocity[1])
    ty, yaw = read(rotation[2])
    if len(t) < 2 or len(ty) == 0:
        return None
    yaw_rad = np.unwrap(_radians(np.asarray(yaw), units[rotation[2]]))
    yaw_at = np.interp(np.asarray(t, dtype=np.float64), np.asarray(ty, dtype=np.float64), yaw_rad)
    trajectory = estimate_trajectory(
        np.asarray(t) / NS,
        np.asarray(vx, float),
        np.asarray(vy, float),
        yaw_at,
        max_gap_s=max_gap_s,
    )
    unit = units[velocity[0]]
    trajectory.unit = unit[:-2] if unit.endswith("/s") else unit
    return trajectory

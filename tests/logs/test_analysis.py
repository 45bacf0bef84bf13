import math

import numpy as np
import pytest

from logs import import_log
from logs.analysis import (
    estimate_trajectory,
    quaternion,
    rotation_matrix,
    trajectory_of,
    values_at,
    values_tree,
)
from logs.series import LogData, Series
from logs.store import open_store, write_store
from tests.logs.dfi_builder import write_dfi

RATE = 200.0


def _rectangle_flight(noise: float = 0.0):
    """Fly forward only at 0.5 m/s, turning 90 degrees right at every corner (the
    rectangle of [Procházka 2016], §5.2.2): 6 m, 3 m, 6 m, 3 m, landing where it started.
    Velocity in mm/s, yaw in degrees."""
    rng = np.random.default_rng(2)
    t, vx, vy, yaw = [], [], [], []
    now, heading = 0.0, 0.0
    for side in (6.0, 3.0, 6.0, 3.0):
        n = int(side / 0.5 * RATE)
        for k in range(n + 1):
            # Ramp speed up and down so each leg starts and ends at rest, like a real drone.
            speed = 500.0 * math.sin(math.pi * k / n) * math.pi / 2
            t.append(now)
            vx.append(speed)
            vy.append(0.0)
            yaw.append(heading)
            now += 1 / RATE
        for _ in range(int(RATE)):  # turn on the spot for one second
            heading += 90.0 / RATE
            t.append(now)
            vx.append(0.0)
            vy.append(0.0)
            yaw.append(heading)
            now += 1 / RATE
    vx = np.array(vx) + rng.normal(size=len(vx)) * noise
    return np.array(t), vx, np.array(vy), np.array(yaw)


def test_trajectory_of_a_rectangle_flight_closes():
    t, vx, vy, yaw = _rectangle_flight(noise=20.0)
    tr = estimate_trajectory(t, vx, vy, np.radians(yaw), max_gap_s=0.02)
    # Far corner (after 6 m north and 3 m east) and back home within 5 cm.
    assert tr.x.max() == pytest.approx(6000, abs=50)
    assert tr.y.min() == pytest.approx(-3000, abs=50)  # y points west: east is negative
    assert math.hypot(tr.x[-1], tr.y[-1]) < 50


def test_trajectory_treats_long_gaps_as_standstill():
    t = np.array([0.0, 0.01, 0.02, 5.0, 5.01])
    v = np.full(5, 1000.0)  # 1 m/s forward, yaw north
    tr = estimate_trajectory(t, v, np.zeros(5), np.zeros(5), max_gap_s=0.02)
    np.testing.assert_allclose(tr.x, [0, 10, 20, 20, 30])
    np.testing.assert_allclose(tr.y, 0)


def test_trajectory_is_found_from_the_special_quantities_of_a_log(tmp_path):
    t, vx, vy, yaw = _rectangle_flight()
    times = np.round(t * 1e9).astype(np.int64)
    log = LogData(format="test")
    log.add(Series("navdata/Velocity/x", vx, times, unit="mm/s", time_source="board"))
    log.add(Series("navdata/Velocity/y", vy, times, unit="mm/s", time_source="board"))
    for axis, values in (("roll", 0 * yaw), ("pitch", 0 * yaw), ("yaw", yaw)):
        log.add(Series(f"navdata/Rotation/{axis}", values, times, unit="deg", time_source="board"))
    write_store(log, tmp_path / "s")
    for source in (log, open_store(tmp_path / "s")):
        tr = trajectory_of(source, max_gap_s=0.02)
        assert tr is not None and tr.unit == "mm"
        assert math.hypot(tr.x[-1], tr.y[-1]) < 5


def test_attitude_applies_yaw_then_pitch_then_roll():
    # Yaw 90 deg (nose east), then pitch 90 deg nose up: the nose points up (-z, z is down).
    r = rotation_matrix(math.radians(90), math.radians(90), 0.0)
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 0, -1], atol=1e-12)
    # Yaw 90 deg, then roll 90 deg right: the right wing (east after the yaw, then south) points down.
    r = rotation_matrix(math.radians(90), 0.0, math.radians(90))
    np.testing.assert_allclose(r @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    # Pitch then roll differs from roll then pitch: the order is really fixed.
    a = rotation_matrix(0.0, math.radians(30), math.radians(40))
    b = rotation_matrix(0.0, 0.0, math.radians(40)) @ rotation_matrix(0.0, math.radians(30), 0.0)
    assert not np.allclose(a, b)


def test_quaternion_is_the_same_rotation_as_the_matrix():
    yaw, pitch, roll = 0.7, -0.3, 1.1
    w, x, y, z = quaternion(yaw, pitch, roll)
    q_matrix = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    np.testing.assert_allclose(q_matrix, rotation_matrix(yaw, pitch, roll), atol=1e-12)
    stack = rotation_matrix(np.array([0.0, yaw]), np.array([0.0, pitch]), np.array([0.0, roll]))
    assert stack.shape == (2, 3, 3)
    np.testing.assert_allclose(stack[0], np.eye(3))


def test_values_at_gives_the_last_sample_at_or_before_the_time(tmp_path):
    log = import_log(write_dfi(tmp_path / "f.dfi"))
    write_store(log, tmp_path / "s")
    for source in (log, open_store(tmp_path / "s")):
        values = values_at(source, 0.0025)  # navdata at 1, 2, 3 ms (board), commands at 5, 6 ms
        assert values["navdata/Altitude"] == {"t": 0.002, "value": 0.75, "label": None}
        assert values["navdata/state"] == {"t": 0.002, "value": 3, "label": "Flying"}
        assert values["commands/Velocity/x"] is None
        assert values_at(source, 0.006)["commands/Velocity/x"]["value"] == 0.2
        tree = values_tree(values)
        assert tree["navdata"]["Rotation"]["yaw"]["value"] == 91.5

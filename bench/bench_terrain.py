"""Terrain clearance speed: one 10 km leg over an imported 1 arc-second SRTM tile.

Run: .venv/bin/python -m bench.bench_terrain

The figure is `terrain.clearance_along` for a 10 km leg across a synthetic N40W009 tile
(3601 x 3601 samples, written byte-exact as SRTM) with a 200 m cone on it, in a database
of its own: one query for the grids under the leg, then every sample of the leg (half a
cell apart) interpolated at once. The baseline, measured in the same run, is the plain
way: `terrain.elevation` point by point along the same samples, in a Python loop. Both
are checked to find the same lowest clearance.

A second figure is the terrain check of a whole mission, a 20 000-leg lawnmower at 5 m
over the same tile (terrain.guard.step_violations: every leg sampled in one pass), against
the same legs checked one `Surface.clearance_along` at a time, in the same run.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_terrain_{os.getpid()}"

LEG_M = 10_000.0
ALTITUDE = 60.0  # metres above mean sea level: the cone (210 m) rises through the leg
TOP = (40.6358, -8.6575)  # the cone's top, in the tile N40W009
SIDE = 3601  # samples per side of a 1 arc-second SRTM tile
GOAL = "the terrain clearance of a 10 km leg in at most 10 ms"
MISSION_LEGS = 20_000
MISSION_GOAL = "the terrain check of a 20 000-leg mission in at most 2 s"


def srtm_tile() -> bytes:
    """Flat ground 10 m high with a cone 200 m high and 500 m wide at its foot, as SRTM
    writes a tile: big-endian int16 samples, rows from the north (latitude 41)."""
    metres = 111_320.0
    north = (41.0 - np.arange(SIDE) / (SIDE - 1) - TOP[0]) * metres
    east = (-9.0 + np.arange(SIDE) / (SIDE - 1) - TOP[1]) * metres * math.cos(math.radians(TOP[0]))
    cone = 200.0 * np.clip(1.0 - np.hypot(north[:, None], east[None, :]) / 500.0, 0.0, None)
    return np.round(10.0 + cone).astype(">i2").tobytes()


def _leg() -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    from onboard.envelope import ned_to_latlon

    start = ned_to_latlon(-LEG_M / 2, 0.0, TOP)
    end = ned_to_latlon(LEG_M / 2, 0.0, TOP)
    return (*start, ALTITUDE), (*end, ALTITUDE)


def _prepare(folder: Path) -> None:
    from django.conf import settings
    from django.db import connection

    from terrain.importer import import_path

    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    settings.TERRAIN_DIR = str(folder / "terrain")
    tile = folder / "N40W009.hgt"
    tile.write_bytes(srtm_tile())
    import_path(tile)


def point_by_point(start, end, samples: int) -> float:  # type: ignore[no-untyped-def]
    """The baseline: one elevation lookup per sample, the lowest clearance kept."""
    import terrain

    lowest = math.inf
    for i in range(samples):
        f = i / (samples - 1)
        lat = start[0] + (end[0] - start[0]) * f
        lon = start[1] + (end[1] - start[1]) * f
        ground = terrain.elevation(lat, lon)
        if ground is not None:
            lowest = min(lowest, start[2] + (end[2] - start[2]) * f - ground)
    return lowest


def lawnmower() -> list[dict]:
    """Take off to 300 m, then rows of 100 waypoints 5 m apart, south of the cone."""
    from onboard.envelope import ned_to_latlon

    steps = [{"command": "takeoff", "params": {"altitude": 300.0}}]
    for i in range(MISSION_LEGS):
        row, col = divmod(i, 100)
        east = 5.0 * (col if row % 2 == 0 else 99 - col)
        lat, lon = ned_to_latlon(-1000.0 - 5.0 * row, east, TOP)
        steps.append({"command": "navigate", "params": {"lat": lat, "lon": lon}})
    return steps


def leg_by_leg(steps: list[dict]) -> float:
    """The baseline: the same legs, one clearance_along each; the lowest clearance."""
    from terrain import guard
    from terrain.lookup import Surface

    moves = [m for m in guard.mission_moves(TOP, steps, (0.0, 0.0, 0.0)) if m[1].kind == "goto"]
    surface = Surface.covering(-9.0, 40.0, -8.0, 41.0)
    ground = surface.elevation(*TOP) or 0.0
    lowest = math.inf
    for _, move, start in moves:
        a, b = (guard._lla(p, TOP, ground) for p in (start, move.ned))
        lowest = min(lowest, surface.clearance_along(a, b).minimum)
    return lowest


def _mission_figure() -> None:
    from bench.common import best_of, record
    from terrain import guard

    steps = lawnmower()
    assert guard.step_violations(None, TOP, steps, (0.0, 0.0, 0.0)) == []
    value = best_of(lambda: guard.step_violations(None, TOP, steps, (0.0, 0.0, 0.0)), repeat=3)
    baseline = best_of(lambda: leg_by_leg(steps), repeat=1)
    record(
        "terrain.mission_20000_legs_s",
        value=value,
        unit="s",
        baseline_name="the same legs, one Surface.clearance_along each",
        baseline_value=baseline,
        higher_is_better=False,
        goal=MISSION_GOAL,
        legs=MISSION_LEGS,
        measured="terrain.guard.step_violations of a lawnmower at 5 m, 300 m above home, "
        "over a 1 arc-second SRTM tile; best of 3",
    )


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    import terrain
    from bench.common import best_of, record

    original_database = connection.settings_dict["NAME"]
    folder = Path(tempfile.mkdtemp(prefix="bench-terrain-"))
    try:
        _prepare(folder)
        start, end = _leg()
        found = terrain.clearance_along(start, end)
        baseline_lowest = point_by_point(start, end, found.samples)
        assert abs(baseline_lowest - found.minimum) < 1e-6, (baseline_lowest, found.minimum)
        value = best_of(lambda: terrain.clearance_along(start, end), repeat=20)
        baseline = best_of(lambda: point_by_point(start, end, found.samples), repeat=3)
        record(
            "terrain.clearance_10km_leg_s",
            value=value,
            unit="s",
            baseline_name="terrain.elevation point by point along the same samples",
            baseline_value=baseline,
            higher_is_better=False,
            goal=GOAL,
            samples=found.samples,
            spacing_m=round(found.spacing_m or 0.0, 2),
            lowest_clearance_m=round(found.minimum or 0.0, 1),
            measured="one leg across a 1 arc-second SRTM tile (3601 x 3601) with a 200 m "
            "cone, database and memory-mapped grid warm; best of 20",
        )
        _mission_figure()
    finally:
        if connection.settings_dict["NAME"] != original_database:
            connection.creation.destroy_test_db(original_database, verbosity=0)
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()

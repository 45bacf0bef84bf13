"""Importing elevation models: every file is read and checked, and its grid written to a
staging folder first; only a complete, valid import becomes TerrainTile rows (bad input:
an error naming the file and the problem, nothing changed)."""

from __future__ import annotations

import shutil
import uuid
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from django.db import transaction

from terrain import store
from terrain.formats import Grid, TerrainError, read_dem
from terrain.models import TerrainTile
from terrain.sources import Limits, Member, dem_files

# Two grids overlap when they share more than this (degrees) both ways: SRTM neighbours
# share their edge rows and columns, which is no overlap.
OVERLAP_EPSILON = 1e-9
Bounds = tuple[float, float, float, float]  # west, south, east, north


@dataclass
class StagedGrid:
    name: str
    kind: str
    bounds: Bounds
    rows: int
    cols: int
    cell_lat: float
    cell_lon: float
    void_count: int
    file: Path


@dataclass
class Staged:
    """Checked grids waiting in their staging folder."""

    folder: Path
    grids: list[StagedGrid] = field(default_factory=list)

    def discard(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


@dataclass
class Imported:
    tiles: list[TerrainTile]
    overlaps: list[str]


def _staged(grid: Grid, file: Path) -> StagedGrid:
    return StagedGrid(
        name=grid.name[:200],
        kind=grid.kind,
        bounds=(grid.west, grid.south, grid.east, grid.north),
        rows=grid.rows,
        cols=grid.cols,
        cell_lat=grid.dlat,
        cell_lon=grid.dlon,
        void_count=grid.void_count,
        file=file,
    )


def stage(members: Iterable[Member], limits: Limits | None = None) -> Staged:
    """Every file read, checked and written aside; the count and bytes held to `limits` as
    they come, whatever a ZIP declared (bad input: the folder goes, TerrainError)."""
    limits = limits or Limits.from_settings()
    staged = Staged(store.incoming_dir() / uuid.uuid4().hex)
    staged.folder.mkdir(parents=True)
    total = 0
    try:
        for name, data in members:
            limits.check_file(name, len(data))
            limits.check_count(len(staged.grids) + 1)
            total += len(data)
            limits.check_total(total)
            grid = read_dem(name, data, limits.samples)
            file = staged.folder / f"{len(staged.grids)}.npy"
            store.write_grid(file, grid.heights)
            staged.grids.append(_staged(grid, file))
    except BaseException:
        staged.discard()
        raise
    if not staged.grids:
        staged.discard()
        raise TerrainError(
            "no elevation file found (expected SRTM .hgt files named like N38W010.hgt, "
            "or GeoTIFF .tif files); nothing was imported"
        )
    return staged


def _overlap(a: Bounds, b: Bounds) -> bool:
    return (
        min(a[2], b[2]) - max(a[0], b[0]) > OVERLAP_EPSILON
        and min(a[3], b[3]) - max(a[1], b[1]) > OVERLAP_EPSILON
    )


def overlaps(staged: Staged) -> list[str]:
    """Each imported grid that overlaps another one of the import or one already stored
    (the newest import is used where they overlap)."""
    found = []
    for i, grid in enumerate(staged.grids):
        for other in staged.grids[:i]:
            if _overlap(grid.bounds, other.bounds):
                found.append(f"{grid.name} overlaps {other.name} of the same import")
        west, south, east, north = grid.bounds
        stored = TerrainTile.objects.filter(
            west__lt=east, east__gt=west, south__lt=north, north__gt=south
        )
        for tile in stored:
            if _overlap(grid.bounds, (tile.west, tile.south, tile.east, tile.north)):
                found.append(f"{grid.name} overlaps {tile.name} (tile {tile.pk}, already imported)")
    return found


def commit(staged: Staged, source: str) -> Imported:
    """The staged grids become tiles, in one transaction; their files move in place."""
    reported = overlaps(staged)
    tiles = []
    store.tiles_dir().mkdir(parents=True, exist_ok=True)
    with transaction.atomic():
        for grid in staged.grids:
            west, south, east, north = grid.bounds
            tile = TerrainTile.objects.create(
                name=grid.name, source=source[:500], kind=grid.kind,
                west=west, south=south, east=east, north=north,
                rows=grid.rows, cols=grid.cols, cell_lat=grid.cell_lat, cell_lon=grid.cell_lon,
                void_count=grid.void_count,
            )  # fmt: skip
            tiles.append(tile)
        moved: list[int] = []
        try:
            for tile, grid in zip(tiles, staged.grids, strict=True):
                grid.file.rename(store.tile_path(tile.pk))
                moved.append(tile.pk)
        except BaseException:
            for tile_id in moved:
                store.delete_grid(tile_id)
            raise
    staged.discard()
    return Imported(tiles, reported)


def import_path(path: Path, limits: Limits | None = None, source: str = "") -> Imported:
    """A file, a folder or a ZIP of elevation files, imported whole or not at all;
    `source` names it on the tiles (the path by default)."""
    limits = limits or Limits.from_settings()
    staged = stage(dem_files(path, limits), limits)
    try:
        return commit(staged, source or str(path))
    except BaseException:
        staged.discard()
        raise


def delete_tiles(tiles: Iterable[TerrainTile]) -> None:
    for tile in tiles:
        store.delete_grid(tile.pk)

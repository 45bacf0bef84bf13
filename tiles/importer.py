"""Importing a tile set: every tile is checked and written to a staging folder first; only
a complete, valid set becomes a TileSet (bad input: an error, nothing changed)."""

from __future__ import annotations

import shutil
import uuid
from dataclasses import dataclass
from pathlib import Path

from django.db import transaction

from tiles import store
from tiles.models import TileSet
from tiles.sources import Limits, Source, open_source
from tiles.store import TileError

Bounds = tuple[float, float, float, float]


@dataclass
class Staged:
    """A checked tile set waiting in its staging folder."""

    folder: Path
    metadata: dict[str, str]
    min_zoom: int
    max_zoom: int
    bounds: Bounds
    count: int
    size: int

    def discard(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def stage(source: Source, limits: Limits | None = None) -> Staged:
    """Every tile checked and written aside; the count and the bytes are held to `limits`
    as they come, whatever the source declared (bad input: the folder goes, TileError)."""
    limits = limits or Limits.from_settings()
    folder = store.root() / "incoming" / uuid.uuid4().hex
    folder.mkdir(parents=True)
    zooms: set[int] = set()
    extents: dict[int, list[int]] = {}  # zoom -> [min x, min y, max x, max y]
    count = size = 0
    try:
        for z, x, y, data in source.tiles:
            limits.check_tile(f"tile {z}/{x}/{y}", len(data))
            limits.check_count(count + 1)
            limits.check_total(size + len(data))
            store.write_tile(folder, z, x, y, data)
            zooms.add(z)
            box = extents.setdefault(z, [x, y, x, y])
            extents[z] = [min(box[0], x), min(box[1], y), max(box[2], x), max(box[3], y)]
            count += 1
            size += len(data)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    if not count:
        shutil.rmtree(folder, ignore_errors=True)
        raise TileError("no tiles found (expected an MBTiles file or <z>/<x>/<y>.png files)")
    top = max(zooms)
    bounds = metadata_bounds(source.metadata) or extent_bounds(top, extents[top])
    return Staged(folder, source.metadata, min(zooms), top, bounds, count, size)


def metadata_bounds(metadata: dict[str, str]) -> Bounds | None:
    """MBTiles `bounds` ("west,south,east,north"), when present and sane."""
    try:
        west, south, east, north = (float(v) for v in metadata["bounds"].split(","))
    except (KeyError, ValueError):
        return None
    if -180 <= west < east <= 180 and -85.06 <= south < north <= 85.06:
        return west, south, east, north
    return None


def extent_bounds(z: int, box: list[int]) -> Bounds:
    west, _, _, north = store.tile_bounds(z, box[0], box[1])
    _, south, east, _ = store.tile_bounds(z, box[2], box[3])
    return west, south, east, north


def commit(staged: Staged, name: str, source: str, attribution: str = "") -> TileSet:
    with transaction.atomic():
        tileset = TileSet.objects.create(
            name=name or staged.metadata.get("name", "") or Path(source).stem or "tiles",
            source=source[:500],
            attribution=(attribution or staged.metadata.get("attribution", ""))[:500],
            min_zoom=staged.min_zoom,
            max_zoom=staged.max_zoom,
            west=staged.bounds[0],
            south=staged.bounds[1],
            east=staged.bounds[2],
            north=staged.bounds[3],
            tile_count=staged.count,
            size_bytes=staged.size,
        )
        store.sets_dir().mkdir(parents=True, exist_ok=True)
        staged.folder.rename(store.sets_dir() / str(tileset.pk))
    return tileset


def import_path(path: Path, name: str = "", scheme: str = "xyz", attribution: str = "") -> TileSet:
    staged = stage(open_source(path, scheme))
    try:
        return commit(staged, name, str(path), attribution)
    except BaseException:
        staged.discard()
        raise


def delete_tiles(tileset: TileSet) -> None:
    shutil.rmtree(store.sets_dir() / str(tileset.pk), ignore_errors=True)

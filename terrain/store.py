"""Where imported grids live: one NumPy `.npy` file of float32 elevations per tile under
TERRAIN_DIR/tiles, read memory-mapped, so a lookup touches only the pages it samples."""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np
from django.conf import settings

# Grids kept open (memory-mapped) per process; each costs a file handle, not its size.
OPEN_GRIDS = 64


def root() -> Path:
    return Path(settings.TERRAIN_DIR)


def tiles_dir() -> Path:
    return root() / "tiles"


def incoming_dir() -> Path:
    return root() / "incoming"


def tile_path(tile_id: int) -> Path:
    return tiles_dir() / f"{tile_id}.npy"


def write_grid(path: Path, heights: np.ndarray) -> None:
    """Written aside then renamed, so a reader never sees half a grid."""
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(f".{path.name}.{os.getpid()}.part")
    with part.open("wb") as out:
        np.save(out, np.ascontiguousarray(heights, dtype=np.float32))
    os.replace(part, path)


@functools.lru_cache(maxsize=OPEN_GRIDS)
def _open(path: str, mtime_ns: int) -> np.ndarray:
    return np.load(path, mmap_mode="r")


def open_grid(tile_id: int) -> np.ndarray | None:
    """The tile's elevations (rows x cols, NaN for voids), or None when its file is gone."""
    path = tile_path(tile_id)
    try:
        mtime = path.stat().st_mtime_ns
    except FileNotFoundError:
        return None
    return _open(str(path), mtime)


def delete_grid(tile_id: int) -> None:
    tile_path(tile_id).unlink(missing_ok=True)

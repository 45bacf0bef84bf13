"""Where tiles live on disk and how one is found: imported sets (newest first), then the
cache of the online source. Plain files, so serving a tile is one stat and one read."""

from __future__ import annotations

import math
import os
from pathlib import Path

from django.conf import settings

# Raster formats Leaflet draws, by their first bytes (the extension is never trusted).
CONTENT_TYPES = {"png": "image/png", "jpg": "image/jpeg", "webp": "image/webp"}
EXTENSIONS = tuple(CONTENT_TYPES)
MAX_ZOOM = 24


class TileError(ValueError):
    """A tile or tile set that cannot be used, with the reason for the operator."""


def sniff_format(data: bytes) -> str | None:
    """png, jpg or webp from the data's magic number; None for anything else."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "png"
    if data.startswith(b"\xff\xd8\xff"):
        return "jpg"
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "webp"
    return None


def root() -> Path:
    return Path(settings.TILES_DIR)


def sets_dir() -> Path:
    return root() / "sets"


def cache_dir() -> Path:
    return root() / "cache"


def check_address(z: int, x: int, y: int) -> None:
    if not 0 <= z <= MAX_ZOOM:
        raise TileError(f"zoom {z} is outside 0–{MAX_ZOOM}")
    if not (0 <= x < 2**z and 0 <= y < 2**z):
        raise TileError(f"tile {z}/{x}/{y} does not exist at zoom {z}")


def tile_path(folder: Path, z: int, x: int, y: int, ext: str) -> Path:
    return folder / str(z) / str(x) / f"{y}.{ext}"


def write_tile(folder: Path, z: int, x: int, y: int, data: bytes) -> str:
    """Store one tile (XYZ address) under `folder`; returns its format."""
    check_address(z, x, y)
    ext = sniff_format(data)
    if ext is None:
        raise TileError(f"tile {z}/{x}/{y} is not a PNG, JPEG or WebP image")
    path = tile_path(folder, z, x, y, ext)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Written aside then renamed, so a reader never sees half a tile.
    part = path.with_name(f".{path.name}.{os.getpid()}.part")
    part.write_bytes(data)
    os.replace(part, path)
    return ext


def set_folders() -> list[Path]:
    """Imported sets, newest first (a newer import wins where two overlap)."""
    try:
        names = [n for n in os.listdir(sets_dir()) if n.isdigit()]
    except FileNotFoundError:
        return []
    return [sets_dir() / n for n in sorted(names, key=int, reverse=True)]


def find_tile(z: int, x: int, y: int) -> Path | None:
    for folder in [*set_folders(), cache_dir()]:
        for ext in EXTENSIONS:
            path = tile_path(folder, z, x, y, ext)
            if path.is_file():
                return path
    return None


def tile_bounds(z: int, x: int, y: int) -> tuple[float, float, float, float]:
    """West, south, east, north (degrees) of an XYZ (Web Mercator) tile."""
    n = 2**z

    def lat(row: int) -> float:
        return math.degrees(math.atan(math.sinh(math.pi * (1 - 2 * row / n))))

    return x / n * 360 - 180, lat(y + 1), (x + 1) / n * 360 - 180, lat(y)

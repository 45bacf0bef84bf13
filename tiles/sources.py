"""Reading tiles out of what an operator imports: an MBTiles file, a z/x/y folder or a ZIP
of one. Each source yields (z, x, y, data) with XYZ addressing, plus its metadata."""

from __future__ import annotations

import re
import sqlite3
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from tiles.store import TileError

# One tile in a folder or ZIP: <z>/<x>/<y>.<ext>, at any depth.
TILE_NAME = re.compile(r"(?:^|/)(\d{1,2})/(\d{1,8})/(\d{1,8})\.(png|jpg|jpeg|webp)$", re.I)
MAX_TILE_BYTES = 4 * 1024 * 1024

Tile = tuple[int, int, int, bytes]


@dataclass
class Source:
    tiles: Iterator[Tile]
    metadata: dict[str, str] = field(default_factory=dict)


def open_source(path: Path, scheme: str = "xyz") -> Source:
    """The tiles of `path` (a .mbtiles file, a folder or a .zip of a folder)."""
    if scheme not in ("xyz", "tms"):
        raise TileError(f"unknown tile scheme {scheme!r} (xyz or tms)")
    if path.is_dir():
        return Source(_flip(_folder_tiles(path), scheme))
    if not path.is_file():
        raise TileError(f"{path} is neither a file nor a folder")
    if zipfile.is_zipfile(path):
        return Source(_flip(_zip_tiles(path), scheme))
    return read_mbtiles(path)


def _flip(tiles: Iterator[Tile], scheme: str) -> Iterator[Tile]:
    for z, x, y, data in tiles:
        yield z, x, (2**z - 1 - y) if scheme == "tms" else y, data


def read_mbtiles(path: Path) -> Source:
    """MBTiles (mbtiles spec 1.3): `tiles(zoom_level, tile_column, tile_row, tile_data)` with
    TMS rows (row 0 at the south), flipped here to XYZ; `metadata(name, value)`."""
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        names = {row[0] for row in con.execute("SELECT name FROM sqlite_master")}
    except sqlite3.DatabaseError as exc:
        raise TileError(f"{path.name} is not an MBTiles file (SQLite: {exc})") from exc
    if "tiles" not in names:
        con.close()
        raise TileError(f"{path.name} has no `tiles` table: not an MBTiles file")
    metadata: dict[str, str] = {}
    if "metadata" in names:
        metadata = {str(k): str(v) for k, v in con.execute("SELECT name, value FROM metadata")}
    if metadata.get("format", "").lower() in ("pbf", "mvt"):
        con.close()
        raise TileError(f"{path.name} holds vector tiles; only raster tiles can be served")
    return Source(_mbtiles_rows(con), metadata)


def _mbtiles_rows(con: sqlite3.Connection) -> Iterator[Tile]:
    try:
        rows = con.execute("SELECT zoom_level, tile_column, tile_row, tile_data FROM tiles")
        for z, x, row, data in rows:
            if not isinstance(data, bytes):
                raise TileError(f"tile {z}/{x}/{row} has no image data")
            yield int(z), int(x), 2 ** int(z) - 1 - int(row), data
    except sqlite3.DatabaseError as exc:
        raise TileError(f"the MBTiles file cannot be read: {exc}") from exc
    finally:
        con.close()


def _folder_tiles(folder: Path) -> Iterator[Tile]:
    for path in sorted(folder.rglob("*")):
        match = TILE_NAME.search(path.relative_to(folder).as_posix())
        if match and path.is_file():
            if path.stat().st_size > MAX_TILE_BYTES:
                raise TileError(f"{path} is larger than {MAX_TILE_BYTES} bytes")
            z, x, y = (int(match.group(i)) for i in (1, 2, 3))
            yield z, x, y, path.read_bytes()


def _zip_tiles(path: Path) -> Iterator[Tile]:
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            match = TILE_NAME.search(info.filename)
            if not match or info.is_dir():
                continue
            # The declared size is checked before reading: a ZIP bomb stops here.
            if info.file_size > MAX_TILE_BYTES:
                raise TileError(f"{info.filename} is larger than {MAX_TILE_BYTES} bytes")
            z, x, y = (int(match.group(i)) for i in (1, 2, 3))
            yield z, x, y, archive.read(info)[: MAX_TILE_BYTES + 1]

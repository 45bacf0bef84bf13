"""Reading tiles out of what an operator imports: an MBTiles file, a z/x/y folder or a ZIP
of one. Each source yields (z, x, y, data) with XYZ addressing, plus its metadata.

What an import may cost is bounded (`Limits`, from the settings): at most
TILES_IMPORT_MAX_TILES tiles of at most MAX_TILE_BYTES each, TILES_IMPORT_MAX_BYTES in
all. What a file declares is checked before anything is read or unpacked: a ZIP's member
count by walking its central directory (before `zipfile` builds an object per member),
its members' declared sizes and compression ratios (MAX_ZIP_RATIO: raster tiles are
already compressed, so a member that unpacks to a hundred times its size is a bomb); an
MBTiles file's row count and tile sizes by one query under a deadline. The importer
(`tiles/importer.py`) counts again as it stores, so a file that lies still stops there.
"""

from __future__ import annotations

import re
import sqlite3
import struct
import time
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from django.conf import settings

from tiles.store import TileError

# One tile in a folder or ZIP: <z>/<x>/<y>.<ext>, at any depth.
TILE_NAME = re.compile(r"(?:^|/)(\d{1,2})/(\d{1,8})/(\d{1,8})\.(png|jpg|jpeg|webp)$", re.I)
MAX_TILE_BYTES = 4 * 1024 * 1024
# A member unpacking to more than this many times its packed size (beyond MAX_ZIP_PLAIN
# bytes, which any small file may reach) is refused as a decompression bomb.
MAX_ZIP_RATIO = 100
MAX_ZIP_PLAIN = 64 * 1024
# Members a ZIP may hold per allowed tile: each tile may sit in a folder of its own.
MEMBERS_PER_TILE = 2
# The MBTiles size query gets this long (a `tiles` view can be made to run for ever).
MBTILES_QUERY_S = 30.0

Tile = tuple[int, int, int, bytes]


@dataclass(frozen=True)
class Limits:
    tiles: int
    total_bytes: int
    tile_bytes: int = MAX_TILE_BYTES

    @classmethod
    def from_settings(cls) -> Limits:
        return cls(int(settings.TILES_IMPORT_MAX_TILES), int(settings.TILES_IMPORT_MAX_BYTES))

    def check_count(self, count: int) -> None:
        if count > self.tiles:
            raise TileError(f"more than {self.tiles} tiles, the limit (TILES_IMPORT_MAX_TILES); nothing was imported")  # fmt: skip

    def check_total(self, total: int) -> None:
        if total > self.total_bytes:
            raise TileError(f"the tiles add up to more than {self.total_bytes} bytes, the limit (TILES_IMPORT_MAX_BYTES); nothing was imported")  # fmt: skip

    def check_tile(self, name: str, size: int) -> None:
        if size > self.tile_bytes:
            raise TileError(f"{name} is larger than {self.tile_bytes} bytes, the limit for one tile; nothing was imported")  # fmt: skip


@dataclass
class Source:
    tiles: Iterator[Tile]
    metadata: dict[str, str] = field(default_factory=dict)


def open_source(path: Path, scheme: str = "xyz", limits: Limits | None = None) -> Source:
    """The tiles of `path` (a .mbtiles file, a folder or a .zip of a folder)."""
    limits = limits or Limits.from_settings()
    if scheme not in ("xyz", "tms"):
        raise TileError(f"unknown tile scheme {scheme!r} (xyz or tms)")
    if path.is_dir():
        return Source(_flip(_folder_tiles(path, limits), scheme))
    if not path.is_file():
        raise TileError(f"{path} is neither a file nor a folder")
    if zipfile.is_zipfile(path):
        return Source(_flip(_zip_tiles(path, limits), scheme))
    return read_mbtiles(path, limits)


def _flip(tiles: Iterator[Tile], scheme: str) -> Iterator[Tile]:
    for z, x, y, data in tiles:
        yield z, x, (2**z - 1 - y) if scheme == "tms" else y, data


def read_mbtiles(path: Path, limits: Limits | None = None) -> Source:
    """MBTiles (mbtiles spec 1.3): `tiles(zoom_level, tile_column, tile_row, tile_data)` with
    TMS rows (row 0 at the south), flipped here to XYZ; `metadata(name, value)`."""
    limits = limits or Limits.from_settings()
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
        rows = con.execute("SELECT name, value FROM metadata LIMIT 1000")
        # A NULL value is no value, not the text "None".
        metadata = {str(k)[:200]: str(v)[:2000] for k, v in rows if v is not None}
    if metadata.get("format", "").lower() in ("pbf", "mvt"):
        con.close()
        raise TileError(f"{path.name} holds vector tiles; only raster tiles can be served")
    try:
        _check_mbtiles_sizes(con, limits)
    except BaseException:
        con.close()
        raise
    return Source(_mbtiles_rows(con, limits), metadata)


def _check_mbtiles_sizes(con: sqlite3.Connection, limits: Limits) -> None:
    """Row count, total and largest tile, from one query under MBTILES_QUERY_S."""
    deadline = time.monotonic() + MBTILES_QUERY_S
    con.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
    try:
        count, total, largest = con.execute(
            "SELECT count(*), total(length(tile_data)), max(length(tile_data)) FROM tiles"
        ).fetchone()
    except sqlite3.OperationalError as exc:
        raise TileError(f"the MBTiles file cannot be read within {MBTILES_QUERY_S:g} s: {exc}") from exc  # fmt: skip
    except sqlite3.DatabaseError as exc:
        raise TileError(f"the MBTiles file cannot be read: {exc}") from exc
    finally:
        con.set_progress_handler(None, 0)
    limits.check_count(int(count))
    limits.check_total(int(total))
    limits.check_tile("a tile of the MBTiles file", int(largest or 0))


def _mbtiles_rows(con: sqlite3.Connection, limits: Limits) -> Iterator[Tile]:
    # A tile over the limit is never fetched: SQLite hands over its length instead.
    query = (
        "SELECT zoom_level, tile_column, tile_row, length(tile_data),"
        " CASE WHEN length(tile_data) <= ? THEN tile_data END FROM tiles"
    )
    try:
        for z, x, row, size, data in con.execute(query, (limits.tile_bytes,)):
            limits.check_tile(f"tile {z}/{x}/{row}", int(size or 0))
            if not isinstance(data, bytes):
                xyz_y = 2 ** int(z) - 1 - int(row)
                raise TileError(f"tile {z}/{x}/{xyz_y} (TMS row {row}) has no image data")
            yield int(z), int(x), 2 ** int(z) - 1 - int(row), data
    except sqlite3.DatabaseError as exc:
        raise TileError(f"the MBTiles file cannot be read: {exc}") from exc
    finally:
        con.close()


def _folder_tiles(folder: Path, limits: Limits) -> Iterator[Tile]:
    for path in sorted(folder.rglob("*")):
        match = TILE_NAME.search(path.relative_to(folder).as_posix())
        if match and path.is_file():
            limits.check_tile(str(path), path.stat().st_size)
            z, x, y = (int(match.group(i)) for i in (1, 2, 3))
            yield z, x, y, path.read_bytes()


def _zip_tiles(path: Path, limits: Limits) -> Iterator[Tile]:
    zip_member_count(path, limits.tiles * MEMBERS_PER_TILE)
    with zipfile.ZipFile(path) as archive:
        members = [(info, TILE_NAME.search(info.filename)) for info in archive.infolist()]
        tiles = [(info, match) for info, match in members if match and not info.is_dir()]
        check_zip_members([info for info, _ in tiles], limits)
        for info, match in tiles:
            z, x, y = (int(match.group(i)) for i in (1, 2, 3))
            # zipfile stops at the declared size, which was checked above.
            with archive.open(info) as member:
                yield z, x, y, member.read(limits.tile_bytes + 1)


def check_zip_members(infos: list[zipfile.ZipInfo], limits: Limits) -> None:
    """Every declared size and ratio, and their sum, before one byte is unpacked."""
    limits.check_count(len(infos))
    for info in infos:
        limits.check_tile(info.filename, info.file_size)
        if info.file_size > MAX_ZIP_PLAIN and info.file_size > MAX_ZIP_RATIO * max(info.compress_size, 1):  # fmt: skip
            raise TileError(f"{info.filename} unpacks to more than {MAX_ZIP_RATIO} times its packed size (a ZIP bomb); nothing was imported")  # fmt: skip
    limits.check_total(sum(info.file_size for info in infos))


# ZIP records (APPNOTE.TXT 6.3, sections 4.3.12, 4.3.14–16).
CENTRAL_ENTRY, END_OF_DIRECTORY, ZIP64_LOCATOR = b"PK\x01\x02", b"PK\x05\x06", b"PK\x06\x07"
ENTRY_HEAD, END_HEAD, ZIP64_END, LOCATOR = 46, 22, 56, 20


def zip_member_count(path: Path, limit: int) -> int:
    """Members in the ZIP's central directory, counted without keeping them; refused
    past `limit`."""
    with path.open("rb") as f:
        start, size = _central_directory(f)
        f.seek(start)
        count = done = 0
        while done < size:
            head = f.read(ENTRY_HEAD)
            if len(head) < ENTRY_HEAD or not head.startswith(CENTRAL_ENTRY):
                break  # zipfile will name what is wrong
            skip = sum(struct.unpack("<HHH", head[28:34]))
            f.seek(skip, 1)
            done += ENTRY_HEAD + skip
            count += 1
            if count > limit:
                raise TileError(f"the ZIP holds more than {limit} members, the limit (TILES_IMPORT_MAX_TILES x {MEMBERS_PER_TILE}); nothing was imported")  # fmt: skip
    return count


def _central_directory(f: BinaryIO) -> tuple[int, int]:
    """Where the central directory starts and its size, found from the end of the file."""
    end = f.seek(0, 2)
    tail_at = max(0, end - END_HEAD - 65535)  # the record, then a comment of up to 64 KiB
    f.seek(tail_at)
    tail = f.read()
    found = tail.rfind(END_OF_DIRECTORY)
    if found < 0 or len(tail) - found < END_HEAD:
        raise TileError("the file is not a ZIP archive (no end of central directory)")
    record_at = tail_at + found
    size = struct.unpack("<I", tail[found + 12 : found + 16])[0]
    if found >= LOCATOR and tail[found - LOCATOR : found - LOCATOR + 4] == ZIP64_LOCATOR:
        record_at -= LOCATOR + ZIP64_END
        f.seek(record_at)
        record = f.read(ZIP64_END)
        size = struct.unpack("<Q", record[40:48])[0] if len(record) == ZIP64_END else size
    return max(0, record_at - size), size

"""Small real tile sets for the tests: PNG tiles (Pillow) in an MBTiles file written with
sqlite3 exactly as the MBTiles 1.3 spec lays it out, or in a z/x/y folder."""

from __future__ import annotations

import io
import sqlite3
from pathlib import Path

from PIL import Image


def png(colour: tuple[int, int, int], size: int = 256) -> bytes:
    out = io.BytesIO()
    Image.new("RGB", (size, size), colour).save(out, "PNG")
    return out.getvalue()


def colour_of(z: int, x: int, y: int) -> tuple[int, int, int]:
    """A colour unique to each XYZ address, so a flipped row shows."""
    return (z * 20 % 256, x * 7 % 256, y * 13 % 256)


# Lisbon, where the fleet tests fly: z14 tiles 7775–7776 x 6277–6278 (XYZ rows).
AREA = {14: [(7775, 6277), (7776, 6277), (7775, 6278), (7776, 6278)], 13: [(3887, 3138)]}


def write_mbtiles(path: Path, area: dict = AREA, metadata: dict | None = None) -> dict:
    """An MBTiles file holding `area` (XYZ addresses); returns {(z, x, y): png bytes}."""
    tiles = {}
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE metadata (name text, value text)")
    con.execute(
        "CREATE TABLE tiles (zoom_level integer, tile_column integer, tile_row integer,"
        " tile_data blob)"
    )
    con.execute("CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row)")
    meta = {"name": "Lisbon test", "format": "png", "minzoom": "13", "maxzoom": "14"}
    meta.update(metadata or {})
    con.executemany("INSERT INTO metadata VALUES (?, ?)", list(meta.items()))
    for z, addresses in area.items():
        for x, y in addresses:
            data = png(colour_of(z, x, y))
            tiles[(z, x, y)] = data
            # The spec's rows are TMS: row 0 at the south.
            con.execute("INSERT INTO tiles VALUES (?, ?, ?, ?)", (z, x, 2**z - 1 - y, data))
    con.commit()
    con.close()
    return tiles


def write_folder(root: Path, area: dict = AREA, tms: bool = False) -> dict:
    tiles = {}
    for z, addresses in area.items():
        for x, y in addresses:
            data = png(colour_of(z, x, y))
            tiles[(z, x, y)] = data
            row = 2**z - 1 - y if tms else y
            (root / str(z) / str(x)).mkdir(parents=True, exist_ok=True)
            (root / str(z) / str(x) / f"{row}.png").write_bytes(data)
    return tiles

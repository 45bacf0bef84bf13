"""A tile import costs at most what the settings state: hostile ZIPs and MBTiles files are
refused naming the limit they break, and nothing is kept."""

from __future__ import annotations

import os
import sqlite3
import zipfile
from pathlib import Path

import pytest
from django.core.management import CommandError, call_command

from tests.tiles.mbtiles import png, write_mbtiles
from tiles import sources
from tiles.models import TileSet

pytestmark = pytest.mark.django_db


@pytest.fixture
def tiles_dir(settings, tmp_path):  # type: ignore[no-untyped-def]
    settings.TILES_DIR = str(tmp_path / "tiles")
    settings.TILE_UPSTREAM_URL = ""
    return Path(settings.TILES_DIR)


def nothing_kept(tiles_dir: Path) -> bool:
    incoming = tiles_dir / "incoming"
    staged = list(incoming.iterdir()) if incoming.exists() else []
    sets = list((tiles_dir / "sets").iterdir()) if (tiles_dir / "sets").exists() else []
    return not TileSet.objects.exists() and staged == [] and sets == []


def refused(path: Path, match: str) -> None:
    with pytest.raises(CommandError, match=match):
        call_command("import_tiles", str(path))


def zip_of(path: Path, members: dict[str, bytes], method: int = zipfile.ZIP_STORED) -> Path:
    with zipfile.ZipFile(path, "w", compression=method) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def tiles_at_zoom(n: int) -> dict[str, bytes]:
    tile = png((10, 20, 30), size=8)
    return {f"18/{100 + i}/200.png": tile for i in range(n)}


def test_a_zip_with_more_members_than_allowed_is_refused_before_it_is_opened(
    tiles_dir, settings, tmp_path
):
    settings.TILES_IMPORT_MAX_TILES = 3
    path = zip_of(tmp_path / "many.zip", {f"junk/{i}.txt": b"" for i in range(7)})
    refused(path, r"more than 6 members.*TILES_IMPORT_MAX_TILES")
    assert nothing_kept(tiles_dir)


def test_a_zip_with_more_tiles_than_allowed_is_refused(tiles_dir, settings, tmp_path):
    settings.TILES_IMPORT_MAX_TILES = 3
    refused(zip_of(tmp_path / "four.zip", tiles_at_zoom(4)), r"more than 3 tiles.*TILES_IMPORT_MAX_TILES")  # fmt: skip
    assert nothing_kept(tiles_dir)
    call_command("import_tiles", str(zip_of(tmp_path / "three.zip", tiles_at_zoom(3))))
    assert TileSet.objects.get().tile_count == 3


def test_a_zip_whose_tiles_add_up_past_the_total_is_refused_before_unpacking(
    tiles_dir, settings, tmp_path
):
    members = tiles_at_zoom(3)
    settings.TILES_IMPORT_MAX_BYTES = sum(len(d) for d in members.values()) - 1
    refused(zip_of(tmp_path / "sum.zip", members), "TILES_IMPORT_MAX_BYTES")
    assert nothing_kept(tiles_dir)


def test_a_zip_member_larger_than_a_tile_may_be_is_refused(tiles_dir, tmp_path):
    big = png((1, 2, 3), size=8) + os.urandom(sources.MAX_TILE_BYTES)
    refused(zip_of(tmp_path / "big.zip", {"14/1/1.png": big}), "the limit for one tile")
    assert nothing_kept(tiles_dir)


def test_a_compression_bomb_is_refused_by_its_ratio(tiles_dir, tmp_path):
    bomb = png((1, 2, 3), size=8) + bytes(3 * 1024 * 1024)  # 3 MiB that packs to ~3 KiB
    path = zip_of(tmp_path / "bomb.zip", {"14/1/1.png": bomb}, zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < 20_000
    refused(path, "ZIP bomb")
    assert nothing_kept(tiles_dir)


def test_the_member_count_is_read_from_a_zip64_directory_too(tmp_path):
    """Past 65 535 members the count lives in the ZIP64 end record (APPNOTE 4.3.14)."""
    path = tmp_path / "z64.zip"
    with zipfile.ZipFile(path, "w") as archive:
        for i in range(65_540):
            archive.writestr(f"d/{i}", b"")
    with path.open("rb") as f:
        f.seek(-22 - 20, 2)
        assert f.read(4) == b"PK\x06\x07"  # the ZIP64 locator is there
    assert sources.zip_member_count(path, 70_000) == 65_540
    with pytest.raises(sources.TileError, match="more than 65539 members"):
        sources.zip_member_count(path, 65_539)


def _mbtiles_with(path: Path, rows: list[tuple[int, int, int, bytes]]) -> Path:
    write_mbtiles(path, area={})
    con = sqlite3.connect(path)
    con.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)", rows)
    con.commit()
    con.close()
    return path


def test_an_mbtiles_file_with_too_many_rows_is_refused(tiles_dir, settings, tmp_path):
    settings.TILES_IMPORT_MAX_TILES = 3
    tile = png((5, 5, 5), size=8)
    path = _mbtiles_with(tmp_path / "rows.mbtiles", [(18, 100 + i, 7, tile) for i in range(4)])
    refused(path, r"more than 3 tiles.*TILES_IMPORT_MAX_TILES")
    assert nothing_kept(tiles_dir)


def test_an_mbtiles_tile_over_the_size_limit_is_refused(tiles_dir, tmp_path):
    big = png((1, 2, 3), size=8) + bytes(sources.MAX_TILE_BYTES)
    path = _mbtiles_with(tmp_path / "big.mbtiles", [(14, 1, 1, big)])
    refused(path, "the limit for one tile")
    assert nothing_kept(tiles_dir)


def test_an_mbtiles_total_over_the_limit_is_refused(tiles_dir, settings, tmp_path):
    tile = png((5, 5, 5), size=8)
    settings.TILES_IMPORT_MAX_BYTES = 2 * len(tile)
    path = _mbtiles_with(tmp_path / "sum.mbtiles", [(18, 100 + i, 7, tile) for i in range(3)])
    refused(path, "TILES_IMPORT_MAX_BYTES")
    assert nothing_kept(tiles_dir)


def test_an_endless_tiles_view_is_stopped_by_the_deadline(tiles_dir, tmp_path, monkeypatch):
    path = tmp_path / "endless.mbtiles"
    con = sqlite3.connect(path)
    con.execute(
        "CREATE VIEW tiles AS WITH RECURSIVE n(i) AS (SELECT 0 UNION ALL SELECT i + 1 FROM n)"
        " SELECT 18 AS zoom_level, i AS tile_column, 0 AS tile_row, x'00' AS tile_data FROM n"
    )
    con.close()
    monkeypatch.setattr(sources, "MBTILES_QUERY_S", 1.0)
    refused(path, "cannot be read within 1 s")
    assert nothing_kept(tiles_dir)


def test_the_admin_upload_names_the_limit_and_keeps_nothing(tiles_dir, client, settings, tmp_path):
    from django.contrib.auth import get_user_model
    from django.core.files.uploadedfile import SimpleUploadedFile

    client.force_login(get_user_model().objects.create_superuser("root", password="pw-1-x"))
    settings.TILES_IMPORT_MAX_TILES = 2
    path = zip_of(tmp_path / "four.zip", tiles_at_zoom(4))
    data = {"file": SimpleUploadedFile(path.name, path.read_bytes()), "scheme": "xyz"}
    response = client.post("/admin/tiles/tileset/add/", data)
    assert response.status_code == 200 and b"TILES_IMPORT_MAX_TILES" in response.content
    assert nothing_kept(tiles_dir)

"""Importing tile sets (MBTiles, folders, ZIPs; command and admin) and serving them at
/tiles/<z>/<x>/<y>.png with caching headers; bad input changes nothing."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import CommandError, call_command

from tests.tiles.mbtiles import png, write_folder, write_mbtiles
from tiles.layer import map_layer
from tiles.models import TileSet

pytestmark = pytest.mark.django_db


@pytest.fixture
def tiles_dir(settings, tmp_path):  # type: ignore[no-untyped-def]
    settings.TILES_DIR = str(tmp_path / "tiles")
    settings.TILE_UPSTREAM_URL = ""
    settings.MAP_TILE_URL = ""
    return Path(settings.TILES_DIR)


@pytest.fixture
def signed_in(client, world):  # type: ignore[no-untyped-def]
    client.force_login(world.operator)
    return client


def sets_on_disk(tiles_dir: Path) -> list[str]:
    folder = tiles_dir / "sets"
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_an_mbtiles_file_is_imported_and_served_with_its_rows_flipped(
    tiles_dir, signed_in, tmp_path
):
    expected = write_mbtiles(tmp_path / "lisbon.mbtiles", metadata={"attribution": "Ours"})
    call_command("import_tiles", str(tmp_path / "lisbon.mbtiles"))
    tileset = TileSet.objects.get()
    assert (tileset.name, tileset.min_zoom, tileset.max_zoom, tileset.tile_count) == (
        "Lisbon test", 13, 14, 5,
    )  # fmt: skip
    # No `bounds` in the metadata: the outline of the z14 tiles, 2 x 2 tiles of 360/2^14°.
    assert tileset.west == pytest.approx(7775 / 2**14 * 360 - 180)
    assert tileset.east == pytest.approx(7777 / 2**14 * 360 - 180)
    assert (round(tileset.south, 4), round(tileset.north, 4)) == (38.7027, 38.7369)
    for (z, x, y), data in expected.items():
        response = signed_in.get(f"/tiles/{z}/{x}/{y}.png")
        assert response.status_code == 200, (z, x, y)
        assert response["Content-Type"] == "image/png"
        assert b"".join(response.streaming_content) == data
        assert "max-age=" in response["Cache-Control"] and response["ETag"]


def test_caching_headers_and_missing_tiles(tiles_dir, signed_in, tmp_path):
    write_mbtiles(tmp_path / "a.mbtiles")
    call_command("import_tiles", str(tmp_path / "a.mbtiles"))
    first = signed_in.get("/tiles/14/7775/6277.png")
    again = signed_in.get("/tiles/14/7775/6277.png", HTTP_IF_NONE_MATCH=first["ETag"])
    assert again.status_code == 304
    assert signed_in.get("/tiles/14/7775/6276.png").status_code == 404  # not in the set
    assert signed_in.get("/tiles/3/8/0.png").status_code == 404  # no such tile at zoom 3
    assert signed_in.get("/tiles/40/0/0.png").status_code == 404


def test_tiles_need_a_signed_in_user(tiles_dir, client, tmp_path):
    write_mbtiles(tmp_path / "a.mbtiles")
    call_command("import_tiles", str(tmp_path / "a.mbtiles"))
    assert client.get("/tiles/14/7775/6277.png").status_code == 302


def test_a_folder_and_a_zip_are_imported_in_either_row_order(tiles_dir, signed_in, tmp_path):
    xyz = write_folder(tmp_path / "xyz")
    call_command("import_tiles", str(tmp_path / "xyz"), "--name", "folder")
    tms_area = {15: [(15551, 12554)]}
    tms = write_folder(tmp_path / "tms", tms_area, tms=True)
    with zipfile.ZipFile(tmp_path / "tms.zip", "w") as archive:
        for path in (tmp_path / "tms").rglob("*.png"):
            archive.write(path, f"export/{path.relative_to(tmp_path / 'tms')}")
    call_command("import_tiles", str(tmp_path / "tms.zip"), "--scheme", "tms")
    assert TileSet.objects.count() == 2
    for (z, x, y), data in {**xyz, **tms}.items():
        assert b"".join(signed_in.get(f"/tiles/{z}/{x}/{y}.png").streaming_content) == data


def test_a_newer_import_wins_where_two_sets_overlap(tiles_dir, signed_in, tmp_path):
    write_folder(tmp_path / "old")
    call_command("import_tiles", str(tmp_path / "old"))
    newer = png((1, 2, 3))
    (tmp_path / "new" / "14" / "7775").mkdir(parents=True)
    (tmp_path / "new" / "14" / "7775" / "6277.png").write_bytes(newer)
    call_command("import_tiles", str(tmp_path / "new"))
    assert b"".join(signed_in.get("/tiles/14/7775/6277.png").streaming_content) == newer


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: p.write_bytes(b"not a database at all" * 100), "not an MBTiles file"),
        (lambda p: write_mbtiles(p, metadata={"format": "pbf"}), "vector tiles"),
        (lambda p: p.mkdir(), "no tiles found"),
    ],
)
def test_bad_input_is_refused_and_nothing_is_kept(tiles_dir, tmp_path, make, message):
    make(tmp_path / "bad.mbtiles")
    with pytest.raises(CommandError, match=message):
        call_command("import_tiles", str(tmp_path / "bad.mbtiles"))
    assert not TileSet.objects.exists() and sets_on_disk(tiles_dir) == []


def test_a_tile_that_is_not_an_image_stops_the_whole_import(tiles_dir, tmp_path):
    write_folder(tmp_path / "set")
    (tmp_path / "set" / "14" / "7776" / "6278.png").write_bytes(b"<html>error</html>")
    with pytest.raises(CommandError, match="not a PNG, JPEG or WebP"):
        call_command("import_tiles", str(tmp_path / "set"))
    assert not TileSet.objects.exists() and sets_on_disk(tiles_dir) == []
    assert list((tiles_dir / "incoming").iterdir()) == []


def test_the_maps_are_told_the_imported_area_and_zooms(tiles_dir, tmp_path):
    assert map_layer() == {"url": ""}  # no tiles: the maps draw their grid alone
    bounds = "-9.2,38.7,-9.1,38.8"
    write_mbtiles(tmp_path / "a.mbtiles", metadata={"bounds": bounds, "attribution": "Ours"})
    call_command("import_tiles", str(tmp_path / "a.mbtiles"))
    layer = map_layer()
    assert layer["url"] == "/tiles/{z}/{x}/{y}.png"
    assert (layer["minZoom"], layer["maxNativeZoom"]) == (13, 14)
    assert layer["bounds"] == [[38.7, -9.2], [38.8, -9.1]] and layer["attribution"] == "Ours"


def upload(client, path: Path, **fields):  # type: ignore[no-untyped-def]
    data = {"file": SimpleUploadedFile(path.name, path.read_bytes()), "scheme": "xyz", **fields}
    return client.post("/admin/tiles/tileset/add/", data)


def test_the_admin_imports_an_upload_and_deletes_its_tiles(tiles_dir, client, tmp_path):
    from django.contrib.auth import get_user_model

    admin = get_user_model().objects.create_superuser("root", password="pw-for-tests-1")
    client.force_login(admin)
    write_mbtiles(tmp_path / "field.mbtiles")
    response = upload(client, tmp_path / "field.mbtiles", name="Field A", attribution="Us")
    assert response.status_code == 302, response.content[:2000]
    tileset = TileSet.objects.get()
    assert (tileset.name, tileset.tile_count, tileset.attribution) == ("Field A", 5, "Us")
    assert sets_on_disk(tiles_dir) == [str(tileset.pk)]
    assert client.get("/tiles/14/7776/6278.png").status_code == 200
    client.post(f"/admin/tiles/tileset/{tileset.pk}/delete/", {"post": "yes"})
    assert not TileSet.objects.exists() and sets_on_disk(tiles_dir) == []
    assert client.get("/tiles/14/7776/6278.png").status_code == 404


def test_the_admin_refuses_an_upload_over_the_limit_or_not_tiles(
    tiles_dir, client, settings, tmp_path
):
    from django.contrib.auth import get_user_model

    client.force_login(get_user_model().objects.create_superuser("root", password="pw-1-x"))
    (tmp_path / "notes.mbtiles").write_text("hello")
    response = upload(client, tmp_path / "notes.mbtiles")
    assert response.status_code == 200 and b"not an MBTiles file" in response.content
    write_mbtiles(tmp_path / "big.mbtiles")
    settings.TILES_UPLOAD_MAX_BYTES = 1000
    response = upload(client, tmp_path / "big.mbtiles")
    assert response.status_code == 200 and b"larger than the limit" in response.content
    assert not TileSet.objects.exists() and sets_on_disk(tiles_dir) == []


def test_an_upload_is_refused_before_django_reads_it(settings):
    """The admin's tile upload path is gated in the ASGI app, as the log upload: a sender
    who is not signed in is answered at once (config/uploadgate.py), and an admitted one
    still meets the size limit there (logs/asgi.py)."""
    from config.asgi import application
    from tests.logs.test_upload_limit_asgi import call

    settings.TILES_UPLOAD_MAX_BYTES = 1000
    too_big = str(1000 + 1024 * 1024).encode()
    status, body, sent = call(
        application.app.application_mapping["http"],
        path="/admin/tiles/tileset/add/",
        headers=[(b"content-length", too_big)],
        chunks=[b"x" * 1000] * 3,
    )
    assert status == 401 and sent == 0 and b"not_authenticated" in body

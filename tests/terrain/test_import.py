"""Importing elevation models as NASA/USGS and GIS tools ship them: SRTM .hgt tiles and
GeoTIFF DEMs, one file, a folder or a ZIP, by command or from the admin. A malformed file
is refused naming the file and the problem, and nothing is stored."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from django.core.management import CommandError, call_command

import terrain
from terrain.formats import TerrainError
from terrain.importer import import_path
from terrain.models import TerrainTile

from .conftest import stored_files
from .dem import GEO_KEYS_WGS84, HOME, hill_tile, with_void, write_geotiff, write_hgt

pytestmark = pytest.mark.django_db


def run_import(path: Path) -> str:
    out = io.StringIO()
    call_command("import_terrain", str(path), stdout=out)
    return out.getvalue()


def test_an_srtm_tile_imported_by_command_gives_its_elevations(terrain_dir, tmp_path, hill):
    output = run_import(write_hgt(tmp_path, hill))
    assert "imported N40W009.hgt: 1201 x 1201 samples, 3 arc-seconds" in output
    tile = TerrainTile.objects.get()
    assert (tile.south, tile.north, tile.west, tile.east) == (40.0, 41.0, -9.0, -8.0)
    assert (tile.rows, tile.cols, tile.void_count, tile.kind) == (1201, 1201, 0, "hgt")
    assert stored_files(terrain_dir) == [f"tiles/{tile.pk}.npy"]
    top = hill.hill_top()
    assert terrain.elevation(*top) == pytest.approx(210.0)
    assert terrain.elevation(*HOME) == pytest.approx(10.0)
    # Between samples: bilinear from the four around the point.
    lat, lon = top[0] + 0.3 * hill.step, top[1] + 0.6 * hill.step
    assert terrain.elevation(lat, lon) == pytest.approx(hill.bilinear(lat, lon), abs=1e-4)
    assert terrain.elevation(42.0, -8.5) is None  # no terrain there


def test_a_one_arc_second_tile_and_its_nasa_zip(terrain_dir, tmp_path):
    fine = hill_tile(3601)
    hgt = write_hgt(tmp_path, fine)
    archive = tmp_path / "N40W009.SRTMGL1.hgt.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(hgt, "N40W009.hgt")
    output = run_import(archive)
    assert "3601 x 3601 samples, 1 arc-seconds" in output
    tile = TerrainTile.objects.get()
    assert tile.cell_lat == pytest.approx(1 / 3600)
    assert terrain.elevation(*fine.hill_top()) == pytest.approx(210.0)


def test_a_geotiff_gives_the_same_ground_as_the_hgt(terrain_dir, tmp_path, hill):
    window = (300, 600, 300, 500)
    tif = write_geotiff(tmp_path / "hill.tif", hill, window)
    output = run_import(tif)
    assert "imported hill.tif: 200 x 300 samples" in output
    tile = TerrainTile.objects.get()
    north, west = hill.latlon(300, 300)
    assert tile.north == pytest.approx(north) and tile.west == pytest.approx(west)
    assert tile.south == pytest.approx(hill.latlon(599, 0)[0])
    top = hill.hill_top()
    assert terrain.elevation(*top) == pytest.approx(210.0)
    lat, lon = top[0] - 0.45 * hill.step, top[1] + 0.2 * hill.step
    assert terrain.elevation(lat, lon) == pytest.approx(hill.bilinear(lat, lon), abs=1e-4)


def test_a_pixel_is_point_geotiff_is_placed_on_its_samples(terrain_dir, tmp_path, hill):
    keys = list(GEO_KEYS_WGS84)
    keys[11] = 2  # GTRasterTypeGeoKey: RasterPixelIsPoint
    tif = write_geotiff(tmp_path / "point.tif", hill, (400, 480, 380, 440), tuple(keys))
    import_path(tif)
    tile = TerrainTile.objects.get()
    # The tiepoint names the corner of the first pixel for pixel-is-area only: read as a
    # point it lies half a cell north-west of the sample.
    lat, lon = hill.latlon(400, 380)
    assert tile.north == pytest.approx(lat + hill.step / 2)
    assert tile.west == pytest.approx(lon - hill.step / 2)


def test_a_folder_and_a_zip_import_every_file_and_report_overlaps(terrain_dir, tmp_path, hill):
    folder = tmp_path / "dem"
    folder.mkdir()
    write_hgt(folder, hill)
    write_geotiff(folder / "patch.tif", hill, (300, 600, 300, 500))
    (folder / "README.txt").write_text("SRTM tiles")
    output = run_import(folder)
    assert TerrainTile.objects.count() == 2
    assert "overlap: patch.tif overlaps N40W009.hgt of the same import" in output
    archive = tmp_path / "dem.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        for path in folder.iterdir():
            z.write(path, f"region/{path.name}")
    imported = import_path(archive)
    assert len(imported.tiles) == 2
    assert any("N40W009.hgt overlaps N40W009.hgt (tile" in o for o in imported.overlaps)
    assert TerrainTile.objects.count() == 4


def test_neighbouring_srtm_tiles_share_an_edge_without_overlapping(terrain_dir, tmp_path, hill):
    write_hgt(tmp_path, hill)
    west = hill_tile()
    west.west -= 1.0
    write_hgt(tmp_path, west)
    imported = import_path(tmp_path)
    assert len(imported.tiles) == 2 and imported.overlaps == []
    # On the shared edge both have the same sample.
    assert terrain.elevation(40.5, -9.0) == pytest.approx(10.0)


def test_voids_are_never_read_as_sea_level(terrain_dir, tmp_path, hill):
    top = hill.hill_top()
    holed = with_void(hill, *top)
    import_path(write_hgt(tmp_path, holed))
    assert TerrainTile.objects.get().void_count == 25
    assert terrain.elevation(*top) is None
    # A point whose four samples include a void has no elevation either.
    row, col = hill.sample_at(*top)
    lat, lon = hill.latlon(row + 2, col + 2)
    assert terrain.elevation(lat - 0.5 * hill.step, lon + 0.5 * hill.step) is None
    assert terrain.elevation(*hill.latlon(row + 3, col + 3)) == pytest.approx(
        float(hill.samples[row + 3, col + 3])
    )


def _refused(path: Path, words: str, terrain_dir: Path) -> None:
    with pytest.raises(CommandError, match=words):
        run_import(path)
    assert not TerrainTile.objects.exists()
    assert stored_files(terrain_dir) == []


def test_a_truncated_or_wrong_sized_hgt_is_refused(terrain_dir, tmp_path, hill):
    data = hill.samples.astype(">i2").tobytes()
    (tmp_path / "N40W009.hgt").write_bytes(data[:-2])
    _refused(tmp_path / "N40W009.hgt", r"N40W009.hgt holds 2884800 bytes; an SRTM", terrain_dir)
    (tmp_path / "N40W009.hgt").write_bytes(np.zeros((1000, 1000), ">i2").tobytes())
    _refused(tmp_path / "N40W009.hgt", "holds 2000000 bytes", terrain_dir)


def test_a_little_endian_hgt_is_refused(terrain_dir, tmp_path, hill):
    (tmp_path / "N40W009.hgt").write_bytes(hill.samples.astype("<i2").tobytes())
    _refused(tmp_path / "N40W009.hgt", "a little-endian file", terrain_dir)


def test_an_hgt_named_off_the_globe_is_refused(terrain_dir, tmp_path, hill):
    write_hgt(tmp_path, hill, "N95W009.hgt")
    _refused(tmp_path / "N95W009.hgt", "not the corner of a 1° tile", terrain_dir)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"tiepoint": False}, "no ModelTiepointTag"),
        ({"geo_keys": (1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32629)}, "EPSG:32629, not EPSG:4326"),
        ({"geo_keys": (1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4258)}, "EPSG:4258, not EPSG:4326"),
        ({"geo_keys": (1, 1, 0, 5, 1024, 0, 1, 2)}, "GeoKeyDirectoryTag holds fewer keys"),
    ],
)
def test_a_geotiff_with_bad_tags_is_refused(terrain_dir, tmp_path, hill, kwargs, words):
    path = write_geotiff(tmp_path / "bad.tif", hill, (0, 20, 0, 20), **kwargs)
    _refused(path, words, terrain_dir)


def test_a_tiff_that_is_not_a_geotiff_or_not_one_band_is_refused(terrain_dir, tmp_path):
    import tifffile

    tifffile.imwrite(tmp_path / "plain.tif", np.zeros((4, 4), np.int16))
    _refused(tmp_path / "plain.tif", "no GeoKeyDirectoryTag", terrain_dir)
    tifffile.imwrite(tmp_path / "rgb.tif", np.zeros((4, 4, 3), np.uint8), photometric="rgb")
    _refused(tmp_path / "rgb.tif", "one band", terrain_dir)
    (tmp_path / "cut.tif").write_bytes((tmp_path / "plain.tif").read_bytes()[:40])
    _refused(tmp_path / "cut.tif", "cut.tif", terrain_dir)


def test_one_bad_file_in_a_zip_refuses_the_whole_import(terrain_dir, tmp_path, hill):
    good = write_hgt(tmp_path, hill)
    archive = tmp_path / "mixed.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(good, "N40W009.hgt")
        z.writestr("N41W009.hgt", good.read_bytes()[:1000])
    _refused(archive, "N41W009.hgt holds 1000 bytes", terrain_dir)


def test_the_import_limits_hold_whatever_a_zip_declares(terrain_dir, tmp_path, hill, settings):
    good = write_hgt(tmp_path, hill)
    archive = tmp_path / "two.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(good, "N40W009.hgt")
        z.write(good, "N40W008.hgt")
    settings.TERRAIN_IMPORT_MAX_FILES = 1
    _refused(archive, "more than 1 elevation files", terrain_dir)
    settings.TERRAIN_IMPORT_MAX_FILES = 10
    settings.TERRAIN_FILE_MAX_BYTES = 1_000_000
    _refused(archive, "larger than 1000000 bytes", terrain_dir)
    settings.TERRAIN_FILE_MAX_BYTES = 10**9
    settings.TERRAIN_MAX_SAMPLES = 1000
    tif = write_geotiff(tmp_path / "big.tif", hill, (0, 100, 0, 100))
    _refused(tif, "more than 1000, the limit", terrain_dir)


def test_a_zip_bomb_is_refused_before_it_is_unpacked(terrain_dir, tmp_path):
    archive = tmp_path / "bomb.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_BZIP2) as z:
        z.writestr("N40W009.hgt", b"\0" * 25_934_402)
    _refused(archive, "a ZIP bomb", terrain_dir)


def test_a_zip_listing_too_many_members_is_refused(terrain_dir, tmp_path, settings):
    settings.TERRAIN_IMPORT_MAX_FILES = 2
    archive = tmp_path / "many.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for i in range(9):
            z.writestr(f"readme{i}.txt", b"")
    _refused(archive, "lists more than 8 members|holds 9 members", terrain_dir)


def test_nothing_to_import_is_said(terrain_dir, tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(TerrainError, match="no elevation file found"):
        import_path(tmp_path / "empty")
    assert stored_files(terrain_dir) == []


def test_between_two_tiles_that_share_no_samples_the_ground_is_the_higher_edge(
    terrain_dir, tmp_path, hill
):
    """Pixel-is-area tiles (as GeoTIFF DEMs are cut) end half a cell beyond their outer
    samples and share none: the strip of one cell between two such tiles has ground."""
    top_row, _ = hill.sample_at(*hill.hill_top())
    import_path(write_geotiff(tmp_path / "north.tif", hill, (300, top_row + 1, 300, 500)))
    import_path(write_geotiff(tmp_path / "south.tif", hill, (top_row + 1, 700, 300, 500)))
    lat_n, lon = hill.latlon(top_row, 400)
    lat_s, _ = hill.latlon(top_row + 1, 400)
    between = (lat_n + lat_s) / 2  # between the north tile's last row and the south's first
    expected = max(hill.bilinear(lat_n, lon), hill.bilinear(lat_s, lon))
    assert terrain.elevation(between, lon) == pytest.approx(expected, abs=1e-4)
    # Within half a cell beyond a tile's outer samples: its edge; further: nothing.
    west_lat, west_lon = hill.latlon(350, 300)
    edge = hill.bilinear(west_lat, west_lon)
    assert terrain.elevation(west_lat, west_lon - 0.4 * hill.step) == pytest.approx(edge, abs=1e-4)
    assert terrain.elevation(west_lat, west_lon - 0.6 * hill.step) is None

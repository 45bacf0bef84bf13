"""GeoTIFF compressions and predictors as GDAL writes them (tests/data/terrain/gdal, made
by its make.sh): every file decodes to the samples of the uncompressed reference, voids
and placement included; broken LZW data is refused with its reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from terrain.formats import TerrainError, read_dem
from terrain.tiffcodecs import CodecError, decode_page, lzw_decode

GDAL = Path(__file__).resolve().parents[1] / "data" / "terrain" / "gdal"
REAL = [
    "deflate_fp_strips.tif",
    "deflate_fp_tiled.tif",
    "deflate_fp_float64.tif",
    "lzw_fp_tiled.tif",
]
WHOLE = [
    "lzw_int16.tif",
    "lzw_int16_predictor2.tif",
    "lzw_int16_predictor2_big_endian_tiled.tif",
    "packbits_int16.tif",
]


def read(name: str):  # type: ignore[no-untyped-def]
    return read_dem(name, (GDAL / name).read_bytes(), 1_000_000)


@pytest.mark.parametrize(
    "name,reference",
    [(n, "reference_float32.tif") for n in REAL] + [(n, "reference_int16.tif") for n in WHOLE],
)
def test_each_compressed_form_gives_the_reference_samples(name, reference):
    grid, ref = read(name), read(reference)
    assert (grid.north, grid.west, grid.dlat, grid.dlon) == (
        ref.north,
        ref.west,
        ref.dlat,
        ref.dlon,
    )
    np.testing.assert_array_equal(grid.heights, ref.heights)
    assert grid.void_count == 3
    assert 300 < np.nanmin(grid.heights) < np.nanmax(grid.heights) < 600


def test_the_floating_point_references_hold_the_grid_gdal_was_given():
    # make.sh's surface at row 1, column 2: 412 + 3.17 * 2 - 1.91 + 25 sin(1/4) cos(2/5).
    expected = 412 + 3.17 * 2 - 1.91 + 25 * np.sin(0.25) * np.cos(0.4)
    assert read("reference_float32.tif").heights[1, 2] == pytest.approx(expected, abs=1e-3)
    assert read("lzw_fp_tiled.tif").heights[1, 2] == pytest.approx(expected, abs=1e-3)


def _segment(name: str) -> tuple[bytes, int, int]:
    """The file's bytes and its first segment's offset and length."""
    import io

    import tifffile

    data = (GDAL / name).read_bytes()
    with tifffile.TiffFile(io.BytesIO(data)) as tif:
        page = tif.pages.first
        return data, int(page.dataoffsets[0]), int(page.databytecounts[0])


def test_an_lzw_code_used_before_it_is_defined_is_refused_naming_the_file():
    data, offset, _ = _segment("lzw_int16.tif")
    # The first code after the clear code (9 bits from bit 9) becomes 511, not yet defined.
    head = int.from_bytes(data[offset : offset + 3], "big")
    broken_head = (head & ~(0x1FF << 6)) | (511 << 6)
    broken = data[:offset] + broken_head.to_bytes(3, "big") + data[offset + 3 :]
    with pytest.raises(TerrainError, match=r"^lzw_int16.tif: .*code 511 before"):
        read_dem("lzw_int16.tif", broken, 1_000_000)


def test_a_cut_lzw_segment_is_refused_as_short():
    data, offset, count = _segment("lzw_int16_predictor2.tif")
    cut = data[:offset] + data[offset : offset + count // 2] + b"\0" * (count - count // 2)
    with pytest.raises(TerrainError, match="bytes where .* were expected|before that code"):
        read_dem("cut.tif", cut, 1_000_000)


def test_lzw_round_trips_the_textbook_cases():
    # Codes written by hand, 9 bits each, most significant bit first: clear, "A", "B",
    # 258 ("AB", defined by the pair before), 260 (the KwKwK case: "ABA"), end.
    codes = [256, 65, 66, 258, 260, 257]
    bits = "".join(f"{c:09b}" for c in codes)
    bits += "0" * (-len(bits) % 8)
    stream = int(bits, 2).to_bytes(len(bits) // 8, "big")
    assert lzw_decode(stream, 100) == b"ABABABA"
    assert lzw_decode(stream, 3) == b"ABA"


def test_the_lzw_of_tiff_before_5_0_is_refused_with_a_way_out():
    with pytest.raises(CodecError, match="before 5.0; re-save it with GDAL"):
        lzw_decode(b"\x00\x01\x02\x03", 10)


def test_tiles_far_larger_than_the_image_are_refused_before_any_is_decompressed():
    from types import SimpleNamespace

    tiny = SimpleNamespace(
        compression=5,
        predictor=1,
        dtype=np.dtype("int16"),
        parent=SimpleNamespace(byteorder="<"),
        shape=(29, 37),
        is_tiled=True,
        tilelength=32768,
        tilewidth=32768,
        dataoffsets=(8,),
        databytecounts=(10,),
    )
    with pytest.raises(CodecError, match="32768 x 32768 tiles are larger than the image"):
        decode_page(tiny, b"\0" * 18)
    # GDAL's 256 x 256 tile over a small grid is fine (refused later only for its data).
    overhang = SimpleNamespace(**{**vars(tiny), "tilelength": 256, "tilewidth": 256})
    with pytest.raises(CodecError, match="bytes where"):
        decode_page(overhang, b"\0" * 18)


@pytest.mark.django_db
def test_an_lzw_and_a_copernicus_form_import_by_command_and_give_the_reference_ground(
    terrain_dir,
):
    import io

    from django.core.management import call_command

    import terrain

    reference = read("reference_float32.tif")
    for name in ("lzw_fp_tiled.tif", "deflate_fp_strips.tif"):
        out = io.StringIO()
        call_command("import_terrain", str(GDAL / name), stdout=out)
        assert f"imported {name}: 37 x 29 samples" in out.getvalue()
    # A sample's centre: the stored ground is the reference's own value there.
    lat, lon = reference.north - 3 * reference.dlat, reference.west + 4 * reference.dlon
    assert terrain.elevation(lat, lon) == pytest.approx(float(reference.heights[3, 4]), abs=1e-3)

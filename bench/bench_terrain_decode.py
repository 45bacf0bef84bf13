"""Reading compressed GeoTIFF elevation models: the forms terrain/tiffcodecs.py decodes.

Run: .venv/bin/python -m bench.bench_terrain_decode

Both figures read an SRTM3-size grid (1201 x 1201 samples, the cone of bench_terrain on
flat ground) with `terrain.formats.read_dem`, as an import does:

- LZW with the horizontal predictor (GDAL's `COMPRESS=LZW PREDICTOR=2`), whole numbers,
  against the same grid in Deflate with the same predictor, which tifffile decodes with
  zlib and numpy: the baseline, in the same run.
- Deflate with the floating-point predictor (Copernicus DEM's form), real numbers,
  against the same grid in Deflate without a predictor.

The files are written here: tifffile encodes Deflate; the LZW strips and the
floating-point prediction, which tifffile leaves to native codecs, are encoded by the
two small encoders below (TIFF 6.0 section 13, Adobe TIFF Technical Note 3), and the
tests read files GDAL wrote in the same forms (tests/data/terrain/gdal). Every form is
checked to give the grid back before it is timed.
"""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np

SIDE = 1201
ROWS_PER_STRIP = 16
GOAL_LZW = "an SRTM3-size LZW tile read in at most 1 s"
GOAL_FLOAT = "an SRTM3-size tile with the floating-point predictor read in at most 0.5 s"
# GeoKeyDirectory: geographic WGS 84, pixel is area; 3 arc-seconds between samples.
GEO_KEYS = (1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326)
STEP = 3 / 3600
COMPRESSION_TAG = 259
PREDICTOR_TAG = 317
SAMPLE_FORMAT_TAG = 339
SAMPLE_SIGNED, SAMPLE_IEEE_FLOAT = 2, 3
DEFLATE, LZW = 8, 5


def grid() -> np.ndarray:
    """Hills up to 300 m with a metre or two of roughness, in whole metres: about as
    compressible as a real SRTM tile (a flat or smooth grid would flatter any codec)."""
    y, x = np.mgrid[0:SIDE, 0:SIDE] / SIDE
    hills = 150.0 * (1 + np.sin(7 * x + 2 * np.cos(5 * y)) * np.cos(4 * y - x))
    rough = np.random.default_rng(2063).normal(0.0, 1.5, (SIDE, SIDE))
    return np.round(hills + rough).astype("<i2")


def lzw_encode(data: bytes) -> bytes:
    """TIFF LZW: a clear code first, codes widening when the next free one needs it, the
    table cleared before it would pass 12 bits, an end code last."""
    out, acc, held, bits = bytearray(), 0, 0, 9

    def put(code: int) -> None:
        nonlocal acc, held
        acc, held = (acc << bits) | code, held + bits
        while held >= 8:
            held -= 8
            out.append((acc >> held) & 0xFF)
        acc &= (1 << held) - 1

    table, following, word = {bytes((i,)): i for i in range(256)}, 258, b""
    put(256)
    for byte in data:
        longer = word + bytes((byte,))
        if longer in table:
            word = longer
            continue
        put(table[word])
        table[longer], following = following, following + 1
        if following == 4094:
            put(256)
            table, following, bits = {bytes((i,)): i for i in range(256)}, 258, 9
        elif following >= 1 << bits:
            bits += 1
        word = bytes((byte,))
    put(table[word])
    put(257)
    if held:
        out.append((acc << (8 - held)) & 0xFF)
    return bytes(out)


def float_predicted(rows: np.ndarray) -> bytes:
    """Rows of float32 as the floating-point predictor stores them, before compression."""
    planes = rows.astype(">f4").view(np.uint8).reshape(len(rows), -1, 4).transpose(0, 2, 1)
    flat = np.ascontiguousarray(planes).reshape(len(rows), -1)
    return np.diff(flat, axis=1, prepend=np.zeros((len(rows), 1), np.uint8)).tobytes()


def geotiff(samples: np.ndarray, **kwargs: object) -> bytes:
    out = io.BytesIO()
    import tifffile

    tags = [
        (34735, "H", len(GEO_KEYS), GEO_KEYS, True),
        (33550, "d", 3, (STEP, STEP, 0.0), True),
        (33922, "d", 6, (0.0, 0.0, 0.0, 8.0, 47.0, 0.0), True),
    ]
    tifffile.imwrite(
        out,
        samples,
        extratags=tags,
        photometric="minisblack",
        rowsperstrip=ROWS_PER_STRIP,
        **kwargs,
    )
    return out.getvalue()


def _retagged(data: bytes, tag: int, old: int, new: int) -> bytes:
    """A one-value SHORT entry of the first directory changed (little-endian file)."""
    entry = struct.pack("<HHIH", tag, 3, 1, old)
    assert data.count(entry) == 1
    return data.replace(entry, struct.pack("<HHIH", tag, 3, 1, new))


def pre_encoded(samples: np.ndarray, encode, predictor: int, compression: int) -> bytes:  # type: ignore[no-untyped-def]
    """The grid's strips encoded here, filed by tifffile as Deflate with the horizontal
    predictor (float32 as int32: tifffile allows it on whole numbers only), then retagged."""
    strips = iter(
        encode(samples[top : top + ROWS_PER_STRIP])
        for top in range(0, len(samples), ROWS_PER_STRIP)
    )
    real = samples.dtype.kind == "f"
    data = geotiff(
        strips,  # type: ignore[arg-type]
        shape=samples.shape,
        dtype=np.int32 if real else samples.dtype,
        compression="zlib",
        predictor=2,  # the entry tifffile writes; the strips are already predicted
    )
    data = _retagged(data, COMPRESSION_TAG, DEFLATE, compression)
    if real:
        data = _retagged(data, SAMPLE_FORMAT_TAG, SAMPLE_SIGNED, SAMPLE_IEEE_FLOAT)
    return data if predictor == 2 else _retagged(data, PREDICTOR_TAG, 2, predictor)


def horizontal(rows: np.ndarray) -> bytes:
    return np.diff(rows, axis=1, prepend=np.zeros((len(rows), 1), rows.dtype)).tobytes()


def _read(data: bytes) -> np.ndarray:
    from terrain.formats import read_dem

    return read_dem("bench.tif", data, SIDE * SIDE).heights


def _figure(
    key: str,
    files: tuple[bytes, bytes],
    expected: np.ndarray,
    baseline: str,
    goal: str,
    measured: str,
) -> None:
    """Time reading the first file against the second, once both give the grid back."""
    from bench.common import best_of, record

    value_file, baseline_file = files
    for data in files:
        assert np.array_equal(_read(data), expected.astype(np.float32))
    record(
        key,
        value=best_of(lambda: _read(value_file), repeat=3),
        unit="s",
        baseline_name=baseline,
        baseline_value=best_of(lambda: _read(baseline_file), repeat=3),
        higher_is_better=False,
        goal=goal,
        samples=SIDE * SIDE,
        measured=measured,
    )


def main() -> None:
    import os

    import django

    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
    django.setup()
    whole = grid()
    _figure(
        "terrain.read_lzw_srtm3_s",
        (
            pre_encoded(whole, lambda rows: lzw_encode(horizontal(rows)), 2, LZW),
            geotiff(whole, compression="zlib", predictor=True),
        ),
        whole,
        baseline="the same grid in Deflate with the horizontal predictor (tifffile)",
        goal=GOAL_LZW,
        measured="read_dem of a 1201 x 1201 int16 GeoTIFF, LZW and Predictor 2 in strips "
        "of 16 rows; best of 3",
    )
    real = whole.astype(np.float32) + 0.25
    _figure(
        "terrain.read_float_predictor_srtm3_s",
        (
            pre_encoded(real, lambda rows: zlib.compress(float_predicted(rows)), 3, DEFLATE),
            geotiff(real, compression="zlib"),
        ),
        real,
        baseline="the same grid in Deflate without a predictor (tifffile)",
        goal=GOAL_FLOAT,
        measured="read_dem of a 1201 x 1201 float32 GeoTIFF, Deflate and Predictor 3 in "
        "strips of 16 rows; best of 3",
    )


if __name__ == "__main__":
    main()

"""Decoding the GeoTIFF segments tifffile leaves to the native imagecodecs package: LZW
compression and the floating-point predictor, both common in published elevation models
(Copernicus DEM tiles are Deflate with the floating-point predictor; GDAL's LZW, with or
without the horizontal predictor, is the usual choice of whoever re-saves a DEM).

- LZW (TIFF 6.0, section 13): codes of 9 to 12 bits, most significant bit first; 256
  clears the table, 257 ends the strip; the code width grows one code early (at 511, 1023
  and 2047 entries), as every TIFF writer since 5.0 does.
- Horizontal predictor (TIFF 6.0, section 14; Predictor 2): each sample after the first of
  a row is stored as its difference from the one before it, modulo the sample's width.
- Floating-point predictor (Adobe Photoshop TIFF Technical Note 3; Predictor 3): each row's
  samples are split into byte planes, most significant byte first, and each byte of the
  row is stored as its difference from the byte before it, modulo 256.

Rows of a segment are decoded whole, then the segment is placed in the image; a tile
reaching past the image's right or bottom edge is cut there.
"""

from __future__ import annotations

import lzma
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

LZW_CLEAR = 256
LZW_END = 257
LZW_MAX_BITS = 12
PREDICTOR_NONE = 1
PREDICTOR_HORIZONTAL = 2
PREDICTOR_FLOATING_POINT = 3
PREDICTORS = {PREDICTOR_NONE, PREDICTOR_HORIZONTAL, PREDICTOR_FLOATING_POINT}
# A tile may overhang a small image (GDAL's default tile is 256 x 256), up to this size.
MAX_SEGMENT_SAMPLES = 1024 * 1024


class CodecError(ValueError):
    """A segment that does not decode, with the reason."""


def lzw_decode(data: bytes, size: int) -> bytes:
    """The first `size` bytes a TIFF LZW strip or tile decodes to (fewer if it ends first)."""
    if data[:2] == b"\x00\x01":
        # Pre-5.0 LZW starts with a clear code written least significant bit first.
        raise CodecError("it uses the LZW variant of TIFF before 5.0; re-save it with GDAL")
    table = [bytes((i,)) for i in range(256)] + [b"", b""]
    out = bytearray()
    bits, buffer, held, previous = 9, 0, 0, b""
    for byte in data:
        buffer = (buffer << 8) | byte
        held += 8
        while held >= bits:
            held -= bits
            code = buffer >> held
            buffer &= (1 << held) - 1
            if code == LZW_END:
                return bytes(out[:size])
            if code == LZW_CLEAR:
                del table[258:]
                bits, previous = 9, b""
                continue
            entry = _lzw_entry(table, code, previous)
            out += entry
            if previous and len(table) < 1 << LZW_MAX_BITS:
                table.append(previous + entry[:1])
            previous = entry
            if len(table) >= (1 << bits) - 1 and bits < LZW_MAX_BITS:
                bits += 1
        if len(out) >= size:
            break
    return bytes(out[:size])


def _lzw_entry(table: list[bytes], code: int, previous: bytes) -> bytes:
    """The string `code` stands for; the one being defined is the previous plus its first
    byte (the KwKwK case of LZW)."""
    if code < len(table) and (code < LZW_CLEAR or previous):
        return table[code]
    if code == len(table) and previous:
        return previous + previous[:1]
    raise CodecError(f"its LZW data holds code {code} before that code was defined")


def _deflate(data: bytes, size: int) -> bytes:
    return zlib.decompressobj().decompress(data, size)


def _lzma(data: bytes, size: int) -> bytes:
    return lzma.LZMADecompressor().decompress(data, size)


DECOMPRESSORS: dict[int, Callable[[bytes, int], bytes]] = {
    1: lambda data, size: data[:size],
    5: lzw_decode,
    8: _deflate,
    32946: _deflate,
    34925: _lzma,
}


def undo_predictor(raw: bytes, rows: int, cols: int, dtype: np.dtype, predictor: int) -> Any:
    """A segment's `rows` x `cols` samples of `dtype` (with its byte order) from its
    decompressed bytes; short data is an error, as the segment would be cut."""
    need = rows * cols * dtype.itemsize
    if len(raw) < need:
        raise CodecError(f"a segment holds {len(raw)} bytes where {need} were expected")
    buffer = np.frombuffer(raw, np.uint8, need)
    if predictor == PREDICTOR_FLOATING_POINT:
        planes = np.cumsum(buffer.reshape(rows, dtype.itemsize * cols), axis=1, dtype=np.uint8)
        msb_first = planes.reshape(rows, dtype.itemsize, cols).transpose(0, 2, 1)
        return np.ascontiguousarray(msb_first).view(dtype.newbyteorder(">")).reshape(rows, cols)
    samples = buffer.view(dtype).reshape(rows, cols)
    if predictor == PREDICTOR_HORIZONTAL:
        native = samples.astype(dtype.newbyteorder("="))
        return np.cumsum(native, axis=1, dtype=native.dtype)
    return samples


def decode_page(page: Any, data: bytes) -> np.ndarray:
    """The first band of a TIFF page (one sample per pixel, checked by the caller), decoded
    segment by segment from the file's bytes."""
    compression, predictor = int(page.compression), int(page.predictor)
    if compression not in DECOMPRESSORS or predictor not in PREDICTORS:
        raise CodecError(f"compression {compression} with predictor {predictor} is not read")
    dtype = np.dtype(page.dtype).newbyteorder(page.parent.byteorder)
    if predictor == PREDICTOR_FLOATING_POINT and dtype.kind != "f":
        raise CodecError("it has the floating-point predictor on whole numbers")
    rows, cols = page.shape
    seg_rows, seg_cols = _segment_shape(page)
    if seg_rows * seg_cols > max(rows * cols, MAX_SEGMENT_SAMPLES):
        # Each segment is decompressed up to its own size: one far larger than the image
        # would let a small file unpack to gigabytes.
        raise CodecError(f"its {seg_cols} x {seg_rows} tiles are larger than the image")
    across, down = -(-cols // seg_cols), -(-rows // seg_rows)
    segments = list(zip(page.dataoffsets, page.databytecounts, strict=True))
    if len(segments) != across * down:
        raise CodecError(f"it lists {len(segments)} strips or tiles where {across * down} fit")
    # Every sample is written below: the segments tile the image exactly.
    image = np.empty((rows, cols), dtype.newbyteorder("="))
    decompress = DECOMPRESSORS[compression]
    for index, (offset, count) in enumerate(segments):
        top, left = (index // across) * seg_rows, (index % across) * seg_cols
        height = seg_rows if page.is_tiled else min(seg_rows, rows - top)
        raw = decompress(data[offset : offset + count], height * seg_cols * dtype.itemsize)
        segment = undo_predictor(raw, height, seg_cols, dtype, predictor)
        block = segment[: rows - top, : cols - left]
        image[top : top + block.shape[0], left : left + block.shape[1]] = block
    return image


def _segment_shape(page: Any) -> tuple[int, int]:
    """Rows and columns of each strip or tile."""
    if page.is_tiled:
        return int(page.tilelength), int(page.tilewidth)
    rows, cols = page.shape
    return min(int(page.rowsperstrip) or rows, rows), cols

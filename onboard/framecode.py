"""The capture time drawn into a video frame, so whoever shows the frame knows its age.

The time travels inside the picture rather than beside it (RTP timestamps or a data
channel): a relay that decodes and re-encodes the stream, a recording, or a still taken
from it all keep the pixels, and the reader needs nothing but the decoded frame.

Layout: the top ``ROWS`` bands of ``CELL_HEIGHT`` pixels each hold ``CELLS_PER_ROW``
cells of ``width // CELLS_PER_ROW`` pixels; a cell is black for 0 and white for 1,
most significant bit first, row by row. The 64 bits are the capture time in
milliseconds since the Unix epoch (48 bits) followed by its CRC-16/CCITT-FALSE
([CRC-16/CCITT-FALSE], 16 bits), so a frame whose strip was damaged by the encoder reads as "no time" rather
than a wrong one. The browser's reader (static/js/live_video.js) decodes the same
layout.
"""

from __future__ import annotations

import numpy as np

CELLS_PER_ROW = 32
ROWS = 2
CELL_HEIGHT = 8
TIME_BITS = 48
CHECK_BITS = 16
BLACK = 16  # studio-range black and white (ITU-R BT.601): what a YUV encoder keeps exactly
WHITE = 235
MIN_WIDTH = CELLS_PER_ROW * 4


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no reflection."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def _bits(ms: int) -> list[int]:
    if not 0 <= ms < 1 << TIME_BITS:
        raise ValueError(f"capture time {ms} ms does not fit in {TIME_BITS} bits")
    check = crc16(ms.to_bytes(TIME_BITS // 8, "big"))
    word = (ms << CHECK_BITS) | check
    total = TIME_BITS + CHECK_BITS
    return [(word >> (total - 1 - i)) & 1 for i in range(total)]


def stamp(rgb: np.ndarray, ms: int) -> None:
    """Draw capture time ``ms`` into the top strip of an RGB frame (height x width x 3)."""
    height, width = rgb.shape[:2]
    if width < MIN_WIDTH or height < ROWS * CELL_HEIGHT:
        raise ValueError(f"a {width}x{height} frame is too small for the time strip")
    cell = width // CELLS_PER_ROW
    rgb[: ROWS * CELL_HEIGHT, :] = BLACK
    for index, bit in enumerate(_bits(ms)):
        if bit:
            row, column = divmod(index, CELLS_PER_ROW)
            top = row * CELL_HEIGHT
            rgb[top : top + CELL_HEIGHT, column * cell : (column + 1) * cell] = WHITE


def read(luma: np.ndarray) -> int | None:
    """The capture time (ms) in a frame's luma plane (height x width), or None when the
    strip is missing or damaged (its check does not match)."""
    height, width = luma.shape[:2]
    if width < MIN_WIDTH or height < ROWS * CELL_HEIGHT:
        return None
    cell = width // CELLS_PER_ROW
    word = 0
    for index in range(TIME_BITS + CHECK_BITS):
        row, column = divmod(index, CELLS_PER_ROW)
        # The middle of the cell: its edges are where a block encoder smears.
        y = row * CELL_HEIGHT + CELL_HEIGHT // 2
        x0 = column * cell + cell // 4
        x1 = max(x0 + 1, column * cell + (3 * cell) // 4)
        level = float(np.mean(luma[y - 1 : y + 1, x0:x1]))
        word = (word << 1) | (1 if level > (BLACK + WHITE) / 2 else 0)
    ms, check = word >> CHECK_BITS, word & ((1 << CHECK_BITS) - 1)
    if crc16(ms.to_bytes(TIME_BITS // 8, "big")) != check:
        return None
    return ms

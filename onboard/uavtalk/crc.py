"""CRC-8 as UAVTalk uses it: polynomial 0x07, initial value 0, no reflection, no final XOR."""

from __future__ import annotations


def _make_table() -> bytes:
    table = bytearray(256)
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table[byte] = crc
    return bytes(table)


CRC8_TABLE = _make_table()


def crc8(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-8 of data, continuing from crc (so a frame can be checked in pieces)."""
    table = CRC8_TABLE
    for byte in data:
        crc = table[crc ^ byte]
    return crc

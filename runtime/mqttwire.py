"""MQTT 3.1.1 packets as bytes, without sockets: the few a lean client needs.

Both hand-written clients use it: the load drones (`firmware.loaddrone`) and the ground's
telemetry reader (`workers.broker.mqtt_reader`), which live without paho for speed. It lives in
onboard because onboard must not import the ground, and it imports nothing but the
standard library.
"""

from __future__ import annotations

import struct


class MqttError(Exception):
    """A packet this client cannot accept; the connection is dropped and retried."""


def encode_string(value: str) -> bytes:
    """A UTF-8 string with its two-byte length (MQTT 3.1.1 §1.5.3)."""
    data = value.encode()
    return struct.pack("!H", len(data)) + data


def encode_varint(n: int) -> bytes:
    """A remaining length: 7 bits a byte, high bit set while more follow (§2.2.3)."""
    out = bytearray()
    while True:
        byte, n = n % 128, n // 128
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def connect_packet(
    client_id: str,
    username: str | None,
    password: str | None,
    *,
    keepalive: int,
    clean_session: bool,
) -> bytes:
    flags = 0x02 if clean_session else 0x00
    payload = encode_string(client_id)
    if username:
        flags |= 0x80
        payload += encode_string(username)
        if password is not None:
            flags |= 0x40
            payload += encode_string(password)
    body = encode_string("MQTT") + bytes([4, flags]) + struct.pack("!H", keepalive) + payload
    return b"\x10" + encode_varint(len(body)) + body


def subscribe_packet(packet_id: int, topic_filter: str, qos: int = 1) -> bytes:
    body = struct.pack("!H", packet_id) + encode_string(topic_filter) + bytes([qos])
    return b"\x82" + encode_varint(len(body)) + body


def publish_packet(
    topic: str, payload: bytes, *, qos: int = 0, packet_id: int = 0, dup: bool = False
) -> bytes:
    header = 0x30 | (qos << 1) | (0x08 if dup else 0)
    body = encode_string(topic) + (struct.pack("!H", packet_id) if qos else b"") + payload
    return bytes([header]) + encode_varint(len(body)) + body


def packet_at(buffer: bytearray, pos: int) -> tuple[int, int] | None:
    """(start, end) of the body of the packet whose first byte is `buffer[pos]`; None
    while the packet is not all in `buffer` yet."""
    end = len(buffer)
    if end - pos < 2:
        return None
    length = 0
    shift = 0
    i = pos + 1
    while True:
        if i >= end:
            return None
        byte = buffer[i]
        length |= (byte & 0x7F) << shift
        i += 1
        if not byte & 0x80:
            break
        shift += 7
        if shift > 21:  # four bytes at most (§2.2.3)
            raise MqttError("malformed remaining length")
    if i + length > end:
        return None
    return i, i + length


def split_packets(buffer: bytearray) -> tuple[list[tuple[int, bytes]], int]:
    """Every complete packet at the start of `buffer` as (first byte, body); bytes used."""
    packets: list[tuple[int, bytes]] = []
    pos = 0
    while (bounds := packet_at(buffer, pos)) is not None:
        start, stop = bounds
        packets.append((buffer[pos], bytes(buffer[start:stop])))
        pos = stop
    return packets, pos

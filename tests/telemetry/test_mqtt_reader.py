"""The minimal MQTT reader's framing: packets split across reads, QoS 1 acks, refusals."""

from __future__ import annotations

import socket
import struct

import pytest

from runtime.mqttwire import encode_string, encode_varint
from workers.broker.mqtt_reader import ProtocolViolation, Subscriber


def publish(topic: str, payload: bytes, packet_id: int | None = None) -> bytes:
    body = encode_string(topic) + (struct.pack("!H", packet_id) if packet_id else b"") + payload
    header = 0x32 if packet_id else 0x30
    return bytes([header]) + encode_varint(len(body)) + body


def _reader(received: list) -> Subscriber:
    return Subscriber(
        "mqtt://u:p@127.0.0.1:1",
        "t",
        "+/telemetry/out",
        lambda topic, payload: received.append((topic, payload)),
    )


def test_packets_split_anywhere_across_reads_are_delivered_whole_and_acked():
    received: list = []
    reader = _reader(received)
    big = b"x" * 300  # a two-byte remaining length
    stream = (
        publish("A/telemetry/out", b'{"a":1}')
        + publish("B/telemetry/out", big, packet_id=7)
        + b"\xd0\x00"  # PINGRESP
        + publish("C/telemetry/out", b"{}")
    )
    ours, broker = socket.socketpair()
    try:
        buffer = bytearray()
        for cut in range(0, len(stream), 5):
            buffer += stream[cut : cut + 5]
            consumed, _ = reader._parse(ours, buffer, True)
            del buffer[:consumed]
        assert not buffer
        assert received == [
            ("A/telemetry/out", b'{"a":1}'),
            ("B/telemetry/out", big),
            ("C/telemetry/out", b"{}"),
        ]
        assert broker.recv(16) == b"\x40\x02\x00\x07"
    finally:
        ours.close()
        broker.close()


def test_a_refused_connection_or_subscription_is_a_protocol_violation():
    reader = _reader([])
    ours, broker = socket.socketpair()
    try:
        with pytest.raises(ProtocolViolation, match="refused the connection"):
            reader._parse(ours, bytearray(b"\x20\x02\x00\x05"), False)
        with pytest.raises(ProtocolViolation, match="subscription"):
            reader._parse(ours, bytearray(b"\x90\x03\x00\x01\x80"), True)
        consumed, connected = reader._parse(
            ours, bytearray(b"\x20\x02\x00\x00\x90\x03\x00\x01\x01"), False
        )
        assert consumed == 9 and connected and reader.subscribed.is_set()
    finally:
        ours.close()
        broker.close()


def test_a_read_ending_inside_the_next_packets_length_still_acks_what_was_delivered():
    received: list = []
    reader = _reader(received)
    delivered = publish("A/telemetry/out", b"{}", packet_id=9)
    next_header = publish("B/telemetry/out", b"x" * 300, packet_id=10)[:2]  # length continues
    ours, broker = socket.socketpair()
    try:
        consumed, _ = reader._parse(ours, bytearray(delivered + next_header), True)
        assert consumed == len(delivered)
        assert received == [("A/telemetry/out", b"{}")]
        broker.settimeout(1)
        assert broker.recv(16) == b"\x40\x02\x00\x09"
    finally:
        ours.close()
        broker.close()


def test_on_messages_takes_every_publish_of_a_read_at_once():
    batches: list[list] = []
    reader = Subscriber(
        "mqtt://u:p@127.0.0.1:1",
        "t",
        "+/telemetry/out",
        lambda topic, payload: pytest.fail("on_message is not used when on_messages is given"),
        on_messages=batches.append,
    )
    stream = (
        publish("A/telemetry/out", b"1")
        + publish("B/telemetry/out", b"2", packet_id=3)
        + publish("C/telemetry/out", b"3")
    )
    ours, broker = socket.socketpair()
    try:
        consumed, _ = reader._parse(ours, bytearray(stream), True)
        assert consumed == len(stream)
        assert batches == [
            [("A/telemetry/out", b"1", None), ("B/telemetry/out", b"2", None),
             ("C/telemetry/out", b"3", None)]
        ]  # fmt: skip
        assert broker.recv(16) == b"\x40\x02\x00\x03", "QoS 1 acked on reading"
        assert reader._parse(ours, bytearray(), True)[0] == 0 and len(batches) == 1
    finally:
        ours.close()
        broker.close()

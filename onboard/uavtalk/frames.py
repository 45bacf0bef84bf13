"""UAVTalk framing: encode frames and decode a byte stream into frames (sans-I/O).

Frame (docs/uavtalk.md): sync 0x3C | type | length u16 (bytes before the CRC) | object id u32 |
[instance id u16] | [timestamp u16 when type has 0x80] | payload | CRC-8.
The decoder never raises on input: whatever it cannot use is counted and skipped.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum

from onboard.uavtalk.crc import CRC8_TABLE, crc8
from onboard.uavtalk.objects import METADATA_STRUCT, ObjectDef, ObjectRegistry, unpack_metadata

SYNC = 0x3C
TIMESTAMPED = 0x80
HEADER = struct.Struct("<BBHI")  # sync, type, length, object id
HEADER_LEN = HEADER.size
MAX_PAYLOAD = 243
MAX_FRAME = 256  # including the CRC byte
ALL_INSTANCES = 0xFFFF


class MessageType(IntEnum):
    OBJ = 0x20
    OBJ_REQ = 0x21
    OBJ_ACK = 0x22
    ACK = 0x23
    NACK = 0x24


@dataclass(frozen=True)
class Frame:
    """One decoded frame. `obj` is None for metadata and for frames without a known object."""

    type: MessageType
    object_id: int
    instance_id: int | None = None
    timestamp_ms: int | None = None
    payload: bytes = b""
    obj: ObjectDef | None = field(default=None, repr=False)
    is_metadata: bool = False

    @property
    def name(self) -> str | None:
        if self.obj is None:
            return None
        return f"{self.obj.name}Meta" if self.is_metadata else self.obj.name

    def fields(self) -> dict:
        """Decoded field values of an OBJ / OBJ_ACK frame (metadata as a small dict)."""
        if self.obj is None:
            raise ValueError(f"frame for unknown object {self.object_id:#010x}")
        if self.is_metadata:
            return unpack_metadata(self.payload)
        return self.obj.unpack(self.payload)


def encode_frame(
    msg_type: int,
    object_id: int,
    payload: bytes = b"",
    *,
    instance_id: int | None = None,
    timestamp_ms: int | None = None,
) -> bytes:
    """Bytes of one frame, CRC included. The instance id is written only when given."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    type_byte = int(msg_type) | (TIMESTAMPED if timestamp_ms is not None else 0)
    extra = b""
    if instance_id is not None:
        extra += struct.pack("<H", instance_id)
    if timestamp_ms is not None:
        extra += struct.pack("<H", timestamp_ms & 0xFFFF)
    length = HEADER_LEN + len(extra) + len(payload)
    body = HEADER.pack(SYNC, type_byte, length, object_id) + extra + payload
    return body + bytes((crc8(body),))


class Codec:
    """Encodes objects by name and decodes frames against one object registry."""

    def __init__(self, registry: ObjectRegistry) -> None:
        self.registry = registry

    def _instance(self, obj: ObjectDef, instance_id: int) -> int | None:
        # dRonin sends the instance id only for multi-instance objects.
        return None if obj.single_instance else instance_id

    def encode_object(
        self,
        name: str,
        values: dict,
        *,
        instance_id: int = 0,
        acked: bool = False,
        timestamp_ms: int | None = None,
    ) -> bytes:
        obj = self.registry[name]
        msg_type = MessageType.OBJ_ACK if acked else MessageType.OBJ
        return encode_frame(
            msg_type,
            obj.id,
            obj.pack(values),
            instance_id=self._instance(obj, instance_id),
            timestamp_ms=timestamp_ms,
        )

    def encode_request(self, name: str, *, instance_id: int = 0) -> bytes:
        obj = self.registry[name]
        return encode_frame(
            MessageType.OBJ_REQ, obj.id, instance_id=self._instance(obj, instance_id)
        )

    def encode_reply(self, msg_type: MessageType, frame: Frame) -> bytes:
        """ACK or NACK answering a received frame (same object and instance)."""
        return encode_frame(msg_type, frame.object_id, instance_id=frame.instance_id)


@dataclass
class DecoderStats:
    frames: int = 0
    bad_crc: int = 0
    truncated: int = 0
    unknown_object: int = 0
    bad_length: int = 0  # length field impossible, or a payload that does not fit the object
    bad_type: int = 0
    skipped_bytes: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)

    @property
    def dropped(self) -> int:
        return self.bad_crc + self.truncated + self.unknown_object + self.bad_length + self.bad_type


_VALID_TYPES = {t.value for t in MessageType}
_TYPES = {t.value: t for t in MessageType}


@dataclass
class FrameDecoder:
    """Feed bytes, get frames. Resynchronises on the next sync byte after anything bad."""

    registry: ObjectRegistry
    stats: DecoderStats = field(default_factory=DecoderStats)
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        self._buf += data
        frames: list[Frame] = []
        buf = self._buf
        pos = 0
        end = len(buf)
        while True:
            start = buf.find(SYNC, pos)
            if start < 0:
                self.stats.skipped_bytes += end - pos
                pos = end
                break
            self.stats.skipped_bytes += start - pos
            pos = start
            if end - pos < HEADER_LEN:
                break
            _, type_byte, length, object_id = HEADER.unpack_from(buf, pos)
            if (type_byte & ~TIMESTAMPED) not in _VALID_TYPES:
                self.stats.bad_type += 1
                pos += 1
                continue
            if length < HEADER_LEN or length + 1 > MAX_FRAME:
                self.stats.bad_length += 1
                pos += 1
                continue
            if end - pos < length + 1:
                break  # wait for the rest of the frame
            if _crc(buf, pos, pos + length) != buf[pos + length]:
                if self._valid_frame_inside(buf, pos + 1, pos + length + 1, end):
                    self.stats.truncated += 1  # a real frame starts inside this one
                else:
                    self.stats.bad_crc += 1
                pos += 1
                continue
            frame = self._parse(type_byte, object_id, bytes(buf[pos + HEADER_LEN : pos + length]))
            pos += length + 1
            if frame is not None:
                self.stats.frames += 1
                frames.append(frame)
        del buf[:pos]
        return frames

    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)

    def close(self) -> None:
        """End of stream: an unfinished frame left over is counted as truncated."""
        if self._buf:
            if self._buf[0] == SYNC:
                self.stats.truncated += 1
            else:
                self.stats.skipped_bytes += len(self._buf)
            self._buf.clear()

    def _valid_frame_inside(self, buf: bytearray, lo: int, hi: int, end: int) -> bool:
        pos = buf.find(SYNC, lo, hi)
        while pos >= 0:
            if end - pos >= HEADER_LEN:
                _, type_byte, length, _ = HEADER.unpack_from(buf, pos)
                if (
                    (type_byte & ~TIMESTAMPED) in _VALID_TYPES
                    and HEADER_LEN <= length < MAX_FRAME
                    and pos + length < end
                    and _crc(buf, pos, pos + length) == buf[pos + length]
                ):
                    return True
            pos = buf.find(SYNC, pos + 1, hi)
        return False

    def _parse(self, type_byte: int, object_id: int, rest: bytes) -> Frame | None:
        msg_type = _TYPES[type_byte & ~TIMESTAMPED]
        ts_len = 2 if type_byte & TIMESTAMPED else 0
        obj = self.registry.by_id.get(object_id)
        is_meta = False
        if obj is None and object_id & 1:
            obj = self.registry.by_id.get(object_id - 1)
            is_meta = obj is not None
        if obj is None:
            if msg_type in (MessageType.OBJ_REQ, MessageType.ACK, MessageType.NACK):
                # Keep it: the other side must be able to NACK / match it by id.
                raw_inst = struct.unpack_from("<H", rest)[0] if len(rest) >= 2 else None
                return Frame(msg_type, object_id, raw_inst)
            self.stats.unknown_object += 1
            if msg_type == MessageType.OBJ_ACK:
                # An acked write of an unknown object is NACKed (the firmware does so);
                # its payload size is unknown, so no instance id is read.
                return Frame(msg_type, object_id, None)
            return None
        size = METADATA_STRUCT.size if is_meta else obj.size
        has_payload = msg_type in (MessageType.OBJ, MessageType.OBJ_ACK)
        body = len(rest) - ts_len - (size if has_payload else 0)
        # Instance id: dRonin sends it for multi-instance objects; LibrePilot always does.
        if body == 2:
            inst: int | None = struct.unpack_from("<H", rest)[0]
            offset = 2
        elif body == 0:
            inst = None if obj.single_instance or is_meta else 0
            offset = 0
        else:
            self.stats.bad_length += 1
            return None
        timestamp = None
        if ts_len:
            timestamp = struct.unpack_from("<H", rest, offset)[0]
            offset += 2
        payload = rest[offset:] if has_payload else b""
        return Frame(msg_type, object_id, inst, timestamp, payload, obj, is_meta)


def _crc(buf: bytearray, lo: int, hi: int) -> int:
    table = CRC8_TABLE
    crc = 0
    for byte in memoryview(buf)[lo:hi]:
        crc = table[crc ^ byte]
    return crc

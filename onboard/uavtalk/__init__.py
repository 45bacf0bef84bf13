"""UAVTalk, the dRonin flight controller's binary protocol, as a sans-I/O codec.

Bytes in, frames out; frames in, bytes out. No serial ports, sockets or files here, so a
live link and a log replay share the same pipeline.
"""

from onboard.uavtalk.crc import crc8
from onboard.uavtalk.frames import (
    ALL_INSTANCES,
    Codec,
    DecoderStats,
    Frame,
    FrameDecoder,
    MessageType,
    encode_frame,
)
from onboard.uavtalk.objects import (
    DefinitionError,
    EncodeError,
    FieldDef,
    ObjectDef,
    ObjectRegistry,
    default_objects_dir,
    metadata_for,
    object_id,
    pack_metadata,
    unpack_metadata,
)

__all__ = [
    "ALL_INSTANCES",
    "Codec",
    "DecoderStats",
    "DefinitionError",
    "EncodeError",
    "FieldDef",
    "Frame",
    "FrameDecoder",
    "MessageType",
    "ObjectDef",
    "ObjectRegistry",
    "crc8",
    "default_objects_dir",
    "encode_frame",
    "metadata_for",
    "object_id",
    "pack_metadata",
    "unpack_metadata",
]

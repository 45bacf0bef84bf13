"""The UAVTalk codec against hand-derived bytes, the firmware's check values and random input."""

from __future__ import annotations

import math
import random
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onboard.uavtalk import (
    Codec,
    DefinitionError,
    EncodeError,
    FrameDecoder,
    MessageType,
    ObjectRegistry,
    crc8,
    encode_frame,
)

from .test_definitions import RELEASE_IDS

REGISTRY = ObjectRegistry.load()
CODEC = Codec(REGISTRY)


def bitwise_crc8(data: bytes) -> int:
    """CRC-8/0x07 computed bit by bit, independent of the table-driven implementation."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def test_crc8_matches_the_standard_check_value():
    assert crc8(b"123456789") == 0xF4
    assert bitwise_crc8(b"123456789") == 0xF4


# dRonin Release-20180729's ids of the objects we define (docs/uavtalk.md).
FIRMWARE_IDS = RELEASE_IDS
# Objects whose id no reference lists: pinned to the id our definition (dRonin's own XML,
# as the release ships it) hashes to, so an edit that changes a field shows here.
PINNED_IDS = {"SystemAlarms": 0x24364184, "WindVelocityActual": 0x6D31D2F8}


def test_every_object_we_define_has_a_checked_id():
    sent = {obj.name for obj in REGISTRY} - {"SharedDefs"}  # SharedDefs is never sent
    assert sent == set(FIRMWARE_IDS) | set(PINNED_IDS)
    for name, expected in {**FIRMWARE_IDS, **PINNED_IDS}.items():
        assert REGISTRY[name].id == expected, f"{name}: {REGISTRY[name].id:#010x}"


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("GCSTelemetryStats", 0xABC72744),
        ("FlightTelemetryStats", 0x2F7E2902),
        ("FlightStatus", 0x4D924972),
        ("GPSPosition", 0x5C1D189E),
        ("AttitudeActual", 0x33DAD5E6),
        ("PositionActual", 0xFA9E2D42),
        ("VelocityActual", 0x5A08F61A),
        ("FlightBatteryState", 0xCAC62F5E),
        ("Waypoint", 0xE02C8266),
        ("PathDesired", 0x3AF5274A),
        ("HomeLocation", 0xCA32B032),
        ("SystemStats", 0xE1DF2D70),
        ("Accels", 0xDD9D5FC0),
        ("Gyros", 0x04228AF6),
        ("BaroAltitude", 0x99622E6A),
        ("FirmwareIAPObj", 0x5E6E8FDC),
        ("UAVTalkReceiver", 0x0D2720A4),
    ],
)
def test_object_ids_match_the_firmware(name, expected):
    assert REGISTRY[name].id == expected


def test_every_required_object_is_defined_with_its_update_period():
    periods = {
        "GPSPosition": 2000,
        "AttitudeActual": 100,
        "PositionActual": 1000,
        "VelocityActual": 1000,
        "FlightBatteryState": 1000,
        "Accels": 1000,
        "Gyros": 1000,
        "BaroAltitude": 1000,
        "SystemStats": 1000,
        "FlightTelemetryStats": 5000,
    }
    for name, period in periods.items():
        assert REGISTRY[name].flight.period_ms == period, name
    for name in ("FlightStatus", "HomeLocation", "Waypoint", "PathDesired", "UAVTalkReceiver"):
        assert name in REGISTRY
    assert REGISTRY["HomeLocation"].settings is True
    assert REGISTRY["Waypoint"].single_instance is False


def test_fields_are_in_wire_order_largest_first_and_stable():
    gps = REGISTRY["GPSPosition"]
    assert gps.field_names == (
        "Latitude", "Longitude", "Altitude", "GeoidSeparation", "Heading", "Groundspeed",
        "Accuracy", "PDOP", "HDOP", "VDOP", "Status", "Satellites",
    )  # fmt: skip
    assert REGISTRY["PathDesired"].field_names[-2:] == ("Waypoint", "Mode")


def test_flight_mode_inherits_the_shared_options():
    mode = REGISTRY["FlightStatus"].field("FlightMode")
    assert mode.options[13] == "PathPlanner"
    assert mode.options[11] == "PositionHold"
    assert mode.options[20] == "Failsafe"


def test_a_subset_of_parent_options_hashes_the_skipped_index():
    parent = """<xml><object name="Shared" settings="false" singleinstance="true">
      <description/><access gcs="readwrite" flight="readwrite"/>
      <logging updatemode="manual" period="0"/>
      <telemetrygcs acked="false" updatemode="manual" period="0"/>
      <telemetryflight acked="false" updatemode="manual" period="0"/>
      <field name="Mode" units="" type="enum" elements="1" options="A,B,C,D"/></object></xml>"""
    child = """<xml><object name="Child" settings="false" singleinstance="true">
      <description/><access gcs="readwrite" flight="readwrite"/>
      <logging updatemode="manual" period="0"/>
      <telemetrygcs acked="false" updatemode="manual" period="0"/>
      <telemetryflight acked="false" updatemode="manual" period="0"/>
      <field name="Mode" units="" type="enum" elements="1" parent="Shared.Mode" options="{}"/>
      </object></xml>"""
    full = ObjectRegistry.from_xml(parent, child.format("A,B,C,D"))["Child"]
    subset = ObjectRegistry.from_xml(parent, child.format("A,C"))["Child"]
    assert subset.field("Mode").option_values == (0, 2)
    assert subset.pack({"Mode": "C"}) == b"\x02"
    assert subset.unpack(b"\x02") == {"Mode": "C"}
    assert full.id != subset.id


def test_handshake_request_frame_matches_hand_built_bytes():
    values = REGISTRY["GCSTelemetryStats"].defaults() | {"Status": "HandshakeReq"}
    frame = CODEC.encode_object("GCSTelemetryStats", values)
    body = (
        b"\x3c\x20"  # sync, OBJ
        + b"\x1d\x00"  # length 29 = 8 header + 21 payload
        + b"\x44\x27\xc7\xab"  # 0xABC72744 little-endian
        + b"\x00" * 20  # TxDataRate, RxDataRate, TxFailures, RxFailures, TxRetries
        + b"\x01"  # Status = HandshakeReq
    )
    assert frame == body + bytes([bitwise_crc8(body)])
    assert frame[-1] == 0x99


def test_request_ack_and_multi_instance_frames_carry_the_right_header():
    req = CODEC.encode_request("FlightStatus")
    assert req[:8] == b"\x3c\x21\x08\x00" + struct.pack("<I", 0x4D924972)
    assert len(req) == 9
    wp = CODEC.encode_object(
        "Waypoint",
        {"Position": [1.0, 2.0, -3.0], "Velocity": 5.0, "ModeParameters": 0.0, "Mode": "Endpoint"},
        instance_id=2,
        acked=True,
    )
    assert wp[1] == MessageType.OBJ_ACK
    assert wp[8:10] == b"\x02\x00"  # instance id
    assert struct.unpack_from("<fff", wp, 10) == (1.0, 2.0, -3.0)
    [frame] = FrameDecoder(REGISTRY).feed(wp)
    assert frame.instance_id == 2
    assert frame.fields()["Position"] == [1.0, 2.0, -3.0]


def test_decoder_accepts_an_instance_id_on_single_instance_objects_and_timestamps():
    obj = REGISTRY["BaroAltitude"]
    payload = obj.pack({"Altitude": 12.5, "Temperature": 20.0, "Pressure": 101.0})
    frame_bytes = encode_frame(MessageType.OBJ, obj.id, payload, instance_id=0, timestamp_ms=1234)
    assert frame_bytes[1] == 0xA0
    [frame] = FrameDecoder(REGISTRY).feed(frame_bytes)
    assert frame.timestamp_ms == 1234
    assert frame.fields()["Altitude"] == 12.5


def test_unknown_option_or_missing_field_is_a_clear_error():
    with pytest.raises(EncodeError, match="unknown option"):
        REGISTRY["FlightStatus"].pack(
            {"Armed": "Maybe", "FlightMode": "Manual", "ControlSource": "Failsafe"}
        )
    with pytest.raises(EncodeError, match="missing"):
        REGISTRY["FlightStatus"].pack({"Armed": "Armed"})
    with pytest.raises(EncodeError):
        REGISTRY["UAVTalkReceiver"].pack({"Channel": [70000] * 8, "RSSI": 0})


def test_a_definition_without_fields_is_rejected():
    bad = """<xml><object name="Empty" settings="false" singleinstance="true">
      <description/><access gcs="readwrite" flight="readwrite"/>
      <logging updatemode="manual" period="0"/>
      <telemetrygcs acked="false" updatemode="manual" period="0"/>
      <telemetryflight acked="false" updatemode="manual" period="0"/></object></xml>"""
    with pytest.raises(DefinitionError, match="no fields"):
        ObjectRegistry.from_xml(bad)


def _value_strategy(obj):
    def for_field(f):
        if f.is_enum:
            element = st.sampled_from(f.options)
        elif f.type_name == "float":
            element = st.floats(width=32, allow_nan=False)
        else:
            bits = {"int8": 8, "int16": 16, "int32": 32, "uint8": 8, "uint16": 16, "uint32": 32}[
                f.type_name
            ]
            signed = not f.type_name.startswith("u")
            lo, hi = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
            element = st.integers(lo, hi)
        if f.elements == 1:
            return element
        return st.lists(element, min_size=f.elements, max_size=f.elements)

    return st.fixed_dictionaries({f.name: for_field(f) for f in obj.fields})


@pytest.mark.parametrize("name", sorted(REGISTRY.by_name))
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_every_object_survives_an_encode_decode_round_trip(name, data):
    obj = REGISTRY[name]
    values = data.draw(_value_strategy(obj))
    instance = data.draw(st.integers(0, 0xFFFE))
    wire = CODEC.encode_object(name, values, instance_id=instance)
    frames = FrameDecoder(REGISTRY).feed(wire)
    assert len(frames) == 1
    assert frames[0].name == name
    assert frames[0].fields() == values
    assert frames[0].instance_id == (None if obj.single_instance else instance)


def _telemetry_frames() -> list[bytes]:
    att = {"q1": 1.0, "q2": 0.0, "q3": 0.0, "q4": 0.0, "Roll": 1.5, "Pitch": -2.0, "Yaw": 90.0}
    pos = {"North": 10.0, "East": -5.0, "Down": -20.0}
    return [
        CODEC.encode_object("AttitudeActual", att),
        CODEC.encode_object("PositionActual", pos),
        CODEC.encode_request("GPSPosition"),
    ]


@settings(max_examples=200, deadline=None)
@given(garbage=st.binary(max_size=600), cut=st.integers(0, 600))
def test_decoder_never_raises_on_random_garbage_and_still_finds_good_frames(garbage, cut):
    good = b"".join(_telemetry_frames())
    decoder = FrameDecoder(REGISTRY)
    frames = []
    stream = garbage[:cut] + good + garbage[cut:] + good
    for i in range(0, len(stream), 7):
        frames += decoder.feed(stream[i : i + 7])
    decoder.close()
    names = [f.name for f in frames if f.obj is not None]
    # The second copy follows garbage that may swallow at most a frame or two of it.
    assert names.count("AttitudeActual") >= 1
    assert decoder.stats.frames == len(frames)


def test_decoder_counts_and_skips_bad_crc_truncated_unknown_and_oversize():
    att, pos, req = _telemetry_frames()
    bad_crc = att[:-1] + bytes([att[-1] ^ 0xFF])
    truncated = pos[:12]
    unknown = encode_frame(MessageType.OBJ, 0x12345678, b"\x01\x02\x03\x04")
    oversize = b"\x3c\x20\xff\x01" + b"\x00" * 8  # length 511
    decoder = FrameDecoder(REGISTRY)
    frames = decoder.feed(b"\x00\xff" + bad_crc + truncated + att + unknown + oversize + pos)
    assert [f.name for f in frames] == ["AttitudeActual", "PositionActual"]
    stats = decoder.stats
    assert stats.bad_crc == 1
    assert stats.truncated == 1
    assert stats.unknown_object == 1
    assert stats.bad_length >= 1
    assert stats.frames == 2


def test_unknown_object_request_is_passed_on_so_it_can_be_nacked():
    wire = encode_frame(MessageType.OBJ_REQ, 0x12345678)
    [frame] = FrameDecoder(REGISTRY).feed(wire)
    assert frame.obj is None and frame.object_id == 0x12345678
    nack = CODEC.encode_reply(MessageType.NACK, frame)
    assert nack[:8] == b"\x3c\x24\x08\x00\x78\x56\x34\x12"


def test_an_acked_write_of_an_unknown_object_is_passed_on_so_it_can_be_nacked():
    wire = encode_frame(MessageType.OBJ_ACK, 0x12345678, b"\x01\x02\x03\x04")
    decoder = FrameDecoder(REGISTRY)
    [frame] = decoder.feed(wire)
    assert frame.obj is None and frame.instance_id is None
    assert decoder.stats.unknown_object == 1
    nack = CODEC.encode_reply(MessageType.NACK, frame)
    assert nack[:8] == b"\x3c\x24\x08\x00\x78\x56\x34\x12"


def test_metadata_frames_decode_as_periods():
    from onboard.uavtalk import metadata_for

    obj = REGISTRY["AttitudeActual"]
    wire = encode_frame(MessageType.OBJ, obj.id + 1, metadata_for(obj))
    [frame] = FrameDecoder(REGISTRY).feed(wire)
    assert frame.is_metadata and frame.name == "AttitudeActualMeta"
    assert frame.fields()["flight_period_ms"] == 100
    assert frame.fields()["flight_update_mode"] == "throttled"


def test_float_fields_keep_their_value_through_the_wire():
    values = REGISTRY["Accels"].defaults() | {"x": 0.1}
    [frame] = FrameDecoder(REGISTRY).feed(CODEC.encode_object("Accels", values))
    assert math.isclose(frame.fields()["x"], 0.1, rel_tol=1e-6)


def test_a_long_random_stream_is_consumed_without_leaking_memory():
    rng = random.Random(7)
    decoder = FrameDecoder(REGISTRY)
    for _ in range(200):
        decoder.feed(bytes(rng.randrange(256) for _ in range(257)))
    assert decoder.pending() < 256

"""The wire contract's parsers: good messages pass, bad ones name the bad field."""

from __future__ import annotations

import base64
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onboard import protocol as p


def control(command: str, **params: object) -> dict:
    return {"request_id": p.new_request_id(), "command": command, "params": params, "ts": 1.0}


def test_new_request_ids_are_32_lowercase_hex_and_differ() -> None:
    ids = {p.new_request_id() for _ in range(100)}
    assert len(ids) == 100
    assert all(p.REQUEST_ID_RE.match(i) for i in ids)


def test_drone_ids_follow_the_contract_pattern() -> None:
    assert p.is_drone_id("REVOLUTION_94E041")
    assert not p.is_drone_id("bad/id")
    assert not p.is_drone_id("x" * 65)
    assert p.topic("D1", "control", "in") == "D1/control/in"
    with pytest.raises(p.ProtocolError):
        p.topic("D1", "telemetry", "in")
    assert p.split_topic("D1/alarms/out") == ("D1", "alarms", "out")


def test_control_request_gets_defaults_and_floats() -> None:
    request = p.parse_control_request(control("takeoff"))
    assert request.params == {"altitude": 10.0}
    request = p.parse_control_request(control("navigate", lat="40.5", lon=-8, altitude_delta=3))
    assert request.params == {"lat": 40.5, "lon": -8.0, "altitude_delta": 3.0}


@pytest.mark.parametrize(
    ("command", "params", "field"),
    [
        ("fly", {}, "command"),
        (["arm"], {}, "command"),
        ("arm", [], "params"),
        ("sleep", {"value": 1}, "command"),  # mission-only
        ("changeN", {}, "params.value"),
        ("changeN", {"value": "ten"}, "params.value"),
        ("changeN", {"value": True}, "params.value"),
        ("changeN", {"value": 10**400}, "params.value"),
        ("navigate", {"lat": 91, "lon": 0}, "params.lat"),
        ("navigate", {"lat": 0, "lon": -180.5}, "params.lon"),
        ("navigate", {"lat": "nan", "lon": 0}, "params.lat"),
        ("objrequest", {"value": "../etc"}, "params.value"),
        ("disarm", {"force": "maybe"}, "params.force"),
    ],
)
def test_bad_control_commands_name_the_field(command: str, params: dict, field: str) -> None:
    with pytest.raises(p.ProtocolError) as caught:
        p.validate_command(command, params)
    assert caught.value.field == field


def test_control_request_without_valid_request_id_is_refused() -> None:
    message = control("arm")
    message["request_id"] = "ABC"
    with pytest.raises(p.ProtocolError) as caught:
        p.parse_control_request(message)
    assert caught.value.field == "request_id"


def test_mission_only_commands_are_accepted_in_missions() -> None:
    assert p.validate_command("wait_for_flight", {}, mission=True) == {
        "horizontal_tolerance": 2.0,
        "vertical_tolerance": 2.0,
    }
    assert p.validate_command("virtualalarm", {"level": "OUT_MEASURE"}, mission=True) == {
        "level": "OUT_MEASURE",
        "message": "",
    }
    with pytest.raises(p.ProtocolError) as caught:
        p.validate_command("virtualalarm", {"level": "PANIC"}, mission=True)
    assert caught.value.field == "params.level"


def test_mission_payload_round_trips_through_base64() -> None:
    steps = [
        {"index": 0, "command": "arm", "params": {}},
        {"index": 1, "command": "takeoff", "params": {"altitude": 15}},
        {"index": 2, "command": "wait_for_flight"},
    ]
    encoded = p.encode_mission_payload("m1", 7, steps)
    decoded = p.decode_mission_payload(encoded)
    assert decoded.mission_id == "m1"
    assert decoded.assignment_id == "7"
    assert [s.command for s in decoded.steps] == ["arm", "takeoff", "wait_for_flight"]
    assert decoded.steps[1].params == {"altitude": 15.0}
    raw = json.loads(base64.b64decode(encoded))
    assert raw["steps"][2]["params"] == {"horizontal_tolerance": 2.0, "vertical_tolerance": 2.0}


@pytest.mark.parametrize(
    ("payload", "field"),
    [
        ("not base64!!", "payload"),
        (base64.b64encode(b"\xff\xfe").decode(), "payload"),
        (base64.b64encode(b"{not json").decode(), "payload"),
        (base64.b64encode(b"[]").decode(), "payload"),
        (
            base64.b64encode(b'{"mission_id": "m", "assignment_id": "a", "steps": []}').decode(),
            "payload.steps",
        ),
        (
            base64.b64encode(
                json.dumps(
                    {
                        "mission_id": "m",
                        "assignment_id": "a",
                        "steps": [{"index": 0, "command": "arm"}, {"index": 0, "command": "land"}],
                    }
                ).encode()
            ).decode(),
            "payload.steps[1].index",
        ),
        (
            base64.b64encode(
                json.dumps(
                    {
                        "mission_id": "m",
                        "assignment_id": "a",
                        "steps": [
                            {"index": 0, "command": "navigate", "params": {"lat": 95, "lon": 0}}
                        ],
                    }
                ).encode()
            ).decode(),
            "payload.steps[0].params.lat",
        ),
    ],
)
def test_malformed_mission_payloads_are_refused_with_the_field(payload: str, field: str) -> None:
    with pytest.raises(p.ProtocolError) as caught:
        p.decode_mission_payload(payload)
    assert caught.value.field == field


def test_mission_requests_parse_start_and_stop() -> None:
    start = p.mission_start("m1", "a1", [{"index": 0, "command": "arm"}])
    parsed = p.parse_mission_request(start.to_dict())
    assert isinstance(parsed, p.MissionStart)
    assert p.decode_mission_payload(parsed.payload).steps[0].command == "arm"
    stop = p.parse_mission_request(
        {"request_id": p.new_request_id(), "action": "stop", "mission_id": "m1"}
    )
    assert isinstance(stop, p.MissionStop)
    with pytest.raises(p.ProtocolError) as caught:
        p.parse_mission_request(
            {"request_id": p.new_request_id(), "action": "hover", "mission_id": "m1"}
        )
    assert caught.value.field == "action"


def test_outgoing_messages_parse_back_to_what_was_sent() -> None:
    position = p.Position(40.63, -8.65, 10.0)
    heartbeat = p.Heartbeat(
        "D1",
        5.0,
        position,
        16.4,
        0.97,
        True,
        True,
        "POSITIONHOLD",
        p.MissionRef("m", "a", 3),
        "uavtalk",
        True,
    )
    assert p.parse_heartbeat(json.loads(p.encode(heartbeat))) == heartbeat
    alarm = p.Alarm("CRITICAL", "battery low", position, "m", "a", 13, ts=3.0)
    assert p.parse_alarm(json.loads(p.encode(alarm))) == alarm
    step = p.StepProgress("m", "a", 7, "navigate", "completed", position, 6.2, {}, ts=4.0)
    assert p.parse_mission_progress(json.loads(p.encode(step))) == step
    progress = p.MissionProgress("m", "a", "accepted", 0.41, ts=4.0)
    assert p.parse_mission_progress(json.loads(p.encode(progress))) == progress
    response = p.ControlResponse(p.new_request_id(), "arm", False, None, "No link.", ts=1.0)
    assert p.parse_control_response(json.loads(p.encode(response))) == response
    telemetry = p.Telemetry((p.TelemetryObject("AttitudeActual", 1.0, {"Roll": 0.1}),), ts=2.0)
    assert p.parse_telemetry(json.loads(p.encode(telemetry))) == telemetry
    picture = p.Picture(
        "IMG_0001.JPG",
        position,
        {"roll": 0.0, "pitch": 0.0, "yaw": 1.0},
        "m",
        2,
        b"\xff\xd8\xff\xe0data",
        ts=1.0,
    )
    assert p.parse_picture(json.loads(p.encode(picture))) == picture
    frame = p.CameraFrame((1.0, 2.0, -3.0), (0.0, 0.0, 0.0, 1.0), b"\xff\xd8x", ts=1.0)
    assert p.parse_camera_frame(json.loads(p.encode(frame))) == frame
    announcement = p.GearAnnouncement({"TYPE": "HEXACOPTER"}, {"CAMERA": "x"}, ts=1.0)
    assert p.parse_gear_message(json.loads(p.encode(announcement))) == announcement


def test_unknown_extra_fields_are_accepted() -> None:
    message = control("arm")
    message["future_field"] = {"x": 1}
    assert p.parse_control_request(message).command == "arm"


def test_parse_message_dispatches_on_the_topic() -> None:
    query = {"request_id": p.new_request_id(), "query": "reading", "sensor": "CO2"}
    drone, channel, parsed = p.parse_message("D1/gear/in", json.dumps(query).encode())
    assert (drone, channel, parsed.sensor) == ("D1", "gear", "CO2")
    with pytest.raises(p.ProtocolError) as caught:
        p.parse_message("D1/gear/in", b"\xff")
    assert caught.value.field == "message"
    with pytest.raises(p.ProtocolError) as caught:
        p.parse_message("D1/gear/in", b'{"request_id": "' + b"a" * 32 + b'", "query": "reading"}')
    assert caught.value.field == "sensor"


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4)
    ),
    max_leaves=12,
)
field_names = st.sampled_from(
    [
        "request_id",
        "command",
        "params",
        "action",
        "mission_id",
        "assignment_id",
        "payload",
        "query",
        "sensor",
        "type",
        "ts",
        "lat",
        "lon",
        "value",
        "steps",
        "index",
        "status",
    ]
)
messages = st.dictionaries(field_names, json_values | st.just(p.new_request_id()), max_size=8)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(sorted(p.PARSERS)), messages | json_values)
def test_any_json_gets_a_parse_or_a_protocol_error_never_a_crash(key, message) -> None:
    try:
        p.PARSERS[key](message)
    except p.ProtocolError as exc:
        assert exc.field is not None


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(p.STEP_COMMANDS), st.dictionaries(field_names, json_values, max_size=4))
def test_any_params_validate_or_name_the_field(command, params) -> None:
    try:
        p.validate_command(command, params, mission=True)
    except p.ProtocolError as exc:
        assert exc.field.startswith("params")

"""The wire contract only grows: the envelope message's optional `remote_id` and the
heartbeat's optional `remote_id`, parsed strictly, absent when not set."""

from __future__ import annotations

import json

import pytest

from onboard import protocol

IDENTITY = {
    "serial_number": "MFR1C123456789ABC",
    "operator_id": "FIN87astrdge12k8",
    "ua_type": 2,
    "description": "Survey north field",
    "operator_location": [40.6301, -8.6579],
}


def envelope_message(**extra: object) -> dict:
    return {"type": "envelope", "ts": 1767225600.0, "envelope": {}, **extra}


def test_an_envelope_message_carries_the_identity_both_ways():
    update = protocol.parse_envelope_update(envelope_message(remote_id=IDENTITY))
    assert update.remote_id == protocol.RemoteIdentity(
        "MFR1C123456789ABC", "FIN87astrdge12k8", 2, "Survey north field", (40.6301, -8.6579)
    )
    again = json.loads(json.dumps(update.to_dict()))
    assert again["remote_id"] == IDENTITY


def test_an_envelope_message_without_identity_is_unchanged_on_the_wire():
    update = protocol.parse_envelope_update(envelope_message())
    assert update.remote_id is None
    assert "remote_id" not in update.to_dict()


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"serial_number": "MFR1C12345678OABC"}, "remote_id.serial_number"),
        ({"serial_number": 5}, "remote_id.serial_number"),
        ({"operator_id": "FIN 87"}, "remote_id.operator_id"),
        ({"ua_type": 16}, "remote_id.ua_type"),
        ({"description": "x" * 24}, "remote_id.description"),
        ({"operator_location": [95, 0]}, "remote_id.operator_location[0]"),
        ({"operator_location": [40.0]}, "remote_id.operator_location"),
    ],
)
def test_a_malformed_identity_refuses_the_message_naming_the_field(change, field):
    with pytest.raises(protocol.ProtocolError) as raised:
        protocol.parse_envelope_update(envelope_message(remote_id={**IDENTITY, **change}))
    assert raised.value.field == field


def heartbeat(**extra: object) -> dict:
    return {
        "type": "heartbeat",
        "drone_id": "MAV_1",
        "ts": 1767225600.5,
        "position": None,
        "battery": {"voltage": 16.4, "remaining": 0.97},
        "armed": False,
        "airborne": False,
        "flight_mode": "GUIDED",
        "mission": None,
        "fc": {"protocol": "mavlink", "connected": True},
        **extra,
    }


def test_a_heartbeat_reports_remote_id_health_only_when_known():
    plain = protocol.parse_heartbeat(heartbeat())
    assert plain.remote_id is None and "remote_id" not in plain.to_dict()
    failing = protocol.parse_heartbeat(
        heartbeat(remote_id={"ok": False, "error": "transmitter fault"})
    )
    assert failing.remote_id == protocol.RemoteIdHealth(False, "transmitter fault", "odid")
    assert failing.to_dict()["remote_id"] == {
        "ok": False,
        "error": "transmitter fault",
        "source": "odid",
    }


@pytest.mark.parametrize(
    "bad", [{"error": "no ok"}, {"ok": "maybe"}, {"ok": False, "error": "x" * 201}, []]
)
def test_a_malformed_health_refuses_the_heartbeat(bad):
    with pytest.raises(protocol.ProtocolError) as raised:
        protocol.parse_heartbeat(heartbeat(remote_id=bad))
    assert raised.value.field.startswith("remote_id")

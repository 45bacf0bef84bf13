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


def test_a_declared_eu_category_and_class_travel_and_undeclared_ones_stay_off_the_wire():
    declared = {**IDENTITY, "eu_category": 2, "eu_class": 6}
    update = protocol.parse_envelope_update(envelope_message(remote_id=declared))
    assert (update.remote_id.eu_category, update.remote_id.eu_class) == (2, 6)
    assert json.loads(json.dumps(update.to_dict()))["remote_id"] == declared
    plain = protocol.parse_envelope_update(envelope_message(remote_id=IDENTITY))
    assert (plain.remote_id.eu_category, plain.remote_id.eu_class) == (0, 0)


def test_the_system_message_carries_the_eu_declaration_under_the_eu_classification():
    from onboard.fc.odid import messages

    def system(identity: protocol.RemoteIdentity) -> tuple:
        fields = dict(messages(identity, None, location_type=0, now=1767225600.0))
        sent = fields["open_drone_id_system"]
        return sent[2], sent[9], sent[10]  # classification type, category, class

    faa = protocol.RemoteIdentity("MFR1C123456789ABC", "FA3ABCDE12")
    assert system(faa) == (0, 0, 0)  # undeclared: nothing said of the EU
    eu = protocol.RemoteIdentity("MFR1C123456789ABC", "FIN87astrdge12k8", eu_category=1, eu_class=3)
    assert system(eu) == (1, 1, 3)  # MAV_ODID_CLASSIFICATION_TYPE_EU, open, C2


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
        ({"eu_category": 4}, "remote_id.eu_category"),
        ({"eu_class": 8}, "remote_id.eu_class"),
        ({"eu_class": "C2"}, "remote_id.eu_class"),
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

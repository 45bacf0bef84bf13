"""Open Drone ID over MAVLink: the identity messages a ground station sends a Remote ID
module, and the module's OPEN_DRONE_ID_ARM_STATUS read back [MAVLink ODID].

The module broadcasts what it is given (ASTM F3411 [ASTM F3411]); ArduPilot and PX4 pass
these messages to it and refuse to arm while its arm status is not 0.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from onboard.protocol import RemoteIdentity

# id_or_mac all zero: the messages are for the module on this vehicle, not relayed ones.
NO_MAC = [0] * 20
# ASTM F3411 timestamps in the System message count seconds from 2019-01-01 00:00 UTC.
EPOCH_2019 = dt.datetime(2019, 1, 1, tzinfo=dt.UTC).timestamp()
UNKNOWN_ALTITUDE = -1000.0  # F3411's "unknown" for heights and areas


def _ascii(text: str, size: int) -> bytes:
    return text.encode("ascii", "replace")[:size].ljust(size, b"\0")


def _eu_operator(identity: RemoteIdentity) -> bool:
    """An EN 4709-002 number starts with 3 letters; an FAA one with FA and a digit."""
    return len(identity.operator_id) == 16 and identity.operator_id[:3].isalpha()


def messages(
    identity: RemoteIdentity,
    operator_position: tuple[float, float] | None,
    *,
    location_type: int,
    now: float,
) -> list[tuple[str, tuple[Any, ...]]]:
    """The four messages (encoder name, fields after target system and component)."""
    # The category and class fields mean something only under the EU classification:
    # an EN 4709-002 operator, or a category or class the ground declared.
    eu = _eu_operator(identity) or bool(identity.eu_category or identity.eu_class)
    classification = (
        mavlink.MAV_ODID_CLASSIFICATION_TYPE_EU
        if eu
        else mavlink.MAV_ODID_CLASSIFICATION_TYPE_UNDECLARED
    )
    lat, lon = operator_position if operator_position is not None else (0.0, 0.0)
    return [
        (
            "open_drone_id_basic_id",
            (
                NO_MAC,
                mavlink.MAV_ODID_ID_TYPE_SERIAL_NUMBER,
                identity.ua_type,
                list(_ascii(identity.serial_number, 20)),
            ),
        ),
        (
            "open_drone_id_operator_id",
            (NO_MAC, mavlink.MAV_ODID_OPERATOR_ID_TYPE_CAA, _ascii(identity.operator_id, 20)),
        ),
        (
            "open_drone_id_self_id",
            (NO_MAC, mavlink.MAV_ODID_DESC_TYPE_TEXT, _ascii(identity.description, 23)),
        ),
        (
            "open_drone_id_system",
            (
                NO_MAC,
                location_type,
                classification,
                round(lat * 1e7),
                round(lon * 1e7),
                1,
                0,
                UNKNOWN_ALTITUDE,
                UNKNOWN_ALTITUDE,
                identity.eu_category if eu else mavlink.MAV_ODID_CATEGORY_EU_UNDECLARED,
                identity.eu_class if eu else mavlink.MAV_ODID_CLASS_EU_UNDECLARED,
                UNKNOWN_ALTITUDE,
                max(0, int(now - EPOCH_2019)),
            ),
        ),
    ]


def location_type(fixed: bool) -> int:
    """FIXED for a position the ground gave, TAKEOFF for the vehicle's home."""
    return (
        mavlink.MAV_ODID_OPERATOR_LOCATION_TYPE_FIXED
        if fixed
        else mavlink.MAV_ODID_OPERATOR_LOCATION_TYPE_TAKEOFF
    )


def send_identity(
    fc: Any, identity: RemoteIdentity, operator_position: tuple[float, float] | None, now: float
) -> None:
    """Send the four messages to the vehicle (every component: the module listens)."""
    kind = location_type(identity.operator_location is not None)
    for name, fields in messages(identity, operator_position, location_type=kind, now=now):
        fc.send(name, fc.target_system, 0, *fields)


def arm_status(fields: dict) -> tuple[bool, str]:
    """(good to arm, error text) from OPEN_DRONE_ID_ARM_STATUS's fields."""
    good = fields.get("status") == mavlink.MAV_ODID_ARM_STATUS_GOOD_TO_ARM
    error = fields.get("error") or ""
    if isinstance(error, bytes | bytearray):
        error = error.rstrip(b"\0").decode("ascii", "replace")
    return good, ("" if good else str(error) or "the module refuses arming")

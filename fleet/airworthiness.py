"""Whether a drone may be armed: a list of reason functions, each naming what keeps the
drone on the ground (None when it has nothing to say).

A drone is airworthy when no reason function names anything. The manual `arm` command
(fleet/commands.py), a mission's start and the choice of drones for replacement,
collaboration and panic (missions/selection.py) all ask here. Further checks (maintenance
due, battery cycles) are functions added to REASONS.

Remote ID (docs/remote-id.md): in the EU a drone of class C1-C3 must broadcast its serial
number [EU 2019/945] and its operator's registration number [EU 2019/947, Art. 14]; a module that
cannot broadcast says so in OPEN_DRONE_ID_ARM_STATUS [MAVLink ODID], which the drone
reports in its heartbeat's `remote_id`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from .models import Drone

Reason = Callable[[Drone], str | None]


@dataclass(frozen=True)
class Verdict:
    airworthy: bool
    reasons: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"airworthy": self.airworthy, "reasons": list(self.reasons)}


def remote_id_health(drone: Drone) -> dict | None:
    """The Remote ID health the drone's last heartbeat reported (None: none reported)."""
    health = (drone.fc or {}).get("remote_id")
    return health if isinstance(health, dict) else None


def remote_id_failing(drone: Drone) -> str | None:
    """The drone's Remote ID module says it must not arm."""
    health = remote_id_health(drone)
    if health is None or health.get("ok"):
        return None
    return f"Remote ID failing: {health.get('error') or 'the module gives no reason'}"


def no_serial_number(drone: Drone) -> str | None:
    if not drone.organisation.require_remote_id or drone.serial_number:
        return None
    return "no serial number: Remote ID broadcasts the drone's ANSI/CTA-2063-A serial"


def no_operator_registration(drone: Drone) -> str | None:
    if not drone.organisation.require_remote_id or drone.organisation.operator_id:
        return None
    return "the organisation has no operator registration number for Remote ID to broadcast"


def no_broadcast(drone: Drone) -> str | None:
    """Remote ID is required, yet neither a module reported in a heartbeat nor an admin
    declared an external one (a flight controller without Open Drone ID)."""
    if not drone.organisation.require_remote_id or drone.remote_id_external:
        return None
    if remote_id_health(drone) is not None:
        return None
    return "no Remote ID broadcast reported: fit a module, or declare an external one"


REASONS: list[Reason] = [
    remote_id_failing,
    no_serial_number,
    no_operator_registration,
    no_broadcast,
]


def verdict(drone: Drone) -> Verdict:
    """Every reason that keeps the drone on the ground, in REASONS' order."""
    reasons = [reason for check in REASONS if (reason := check(drone)) is not None]
    return Verdict(airworthy=not reasons, reasons=reasons)


def refusal(drone: Drone) -> str | None:
    """The sentence a refused arm or mission start gives, or None when airworthy."""
    found = verdict(drone)
    if found.airworthy:
        return None
    return f"Drone {drone.drone_id} is not airworthy: " + "; ".join(found.reasons) + "."

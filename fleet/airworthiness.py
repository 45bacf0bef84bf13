"""Whether a drone may be armed: a list of reason functions, each naming what keeps the
drone on the ground (None when it has nothing to say).

A drone is airworthy when no reason function names anything. The manual `arm` command
(fleet/commands.py), a mission's start and the choice of drones for replacement,
collaboration and panic (missions/selection.py) all ask here. Further checks (maintenance
due, battery cycles) are functions added to REASONS; one that reads the database also
gives a batch form in MANY, so that `verdicts` judges many drones of an organisation in a
fixed number of queries. A reason that reads the database may also give its read as
annotations of one drone's own lookup (`lookup_reads`), which a manual `arm` makes in the
statement that finds the drone: the reason then answers from the drone's row when it
can, and reads as before when the annotation leaves it in doubt.

Remote ID (docs/remote-id.md): in the EU a drone of class C1-C3 must broadcast its serial
number [EU 2019/945] and its operator's registration number [EU 2019/947, Art. 14]; a module that
cannot broadcast says so in OPEN_DRONE_ID_ARM_STATUS [MAVLink ODID], which the drone
reports in its heartbeat's `remote_id`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from django.conf import settings
from django.db.models import Exists, OuterRef
from django.db.models.fields.json import KeyTextTransform
from django.utils.module_loading import import_string

from .models import Drone, Organisation
from .wind import above_limit as wind_above_limit

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


# The annotation a drone looked up with `lookup_reads` carries: False when none of its
# packs, and no pack of its organisation with the serial its flight controller reports, is
# retired (so `battery_retired` has nothing to say); True when one is (the reason is read).
MAY_CARRY_RETIRED = "airworthiness_may_carry_retired"


def lookup_reads() -> dict:
    """The reads of the reasons in REASONS, as annotations of a query of drones (each
    named by the attribute its reason looks for): the batteries' here, maintenance's from
    the app that keeps it (MAINTENANCE_AIRWORTHINESS_LOOKUP)."""
    serial = KeyTextTransform("battery_serial", OuterRef("fc"))
    retired = Exists(
        Organisation.objects.filter(
            pk=OuterRef("organisation_id"), batteries__serial=serial, batteries__retired=True
        )
    ) | Exists(Drone.objects.filter(pk=OuterRef("pk"), batteries__retired=True))
    return {
        MAY_CARRY_RETIRED: retired,
        **import_string(settings.MAINTENANCE_AIRWORTHINESS_LOOKUP)(),
    }


def _nothing_retired(drones: Sequence[Drone]) -> bool:
    return all(getattr(d, MAY_CARRY_RETIRED, True) is False for d in drones)


def maintenance_due_many(drones: Sequence[Drone]) -> list[str | None]:
    """A maintenance task due or overdue, or a service bulletin or finding not signed off
    (docs/maintenance.md), for each drone in a fixed number of queries; the maintenance
    app answers, named in settings because it builds on fleet."""
    return import_string(settings.MAINTENANCE_AIRWORTHINESS_CHECK)(drones)


def maintenance_due(drone: Drone) -> str | None:
    return maintenance_due_many([drone])[0]


def battery_retired(drone: Drone) -> str | None:
    """The pack the drone carries is retired (docs/batteries.md): its health is below the
    organisation's threshold or its cycles above its limit. The pack is the one its flight
    controller reports by serial, else the one a member chose; the batteries app keeps
    the verdict on the pack (reached here by its relations, as it builds on fleet)."""
    return battery_retired_many([drone])[0]


def _reported_serial(drone: Drone) -> str | None:
    serial = (drone.fc or {}).get("battery_serial")
    return serial if isinstance(serial, str) and serial else None


def battery_retired_many(drones: Sequence[Drone]) -> list[str | None]:
    """`battery_retired` of each drone in at most two queries: the retired packs among
    those reported by serial (a serial is unique in its organisation), and the first
    retired pack by serial among those chosen on each other drone. A drone not stored
    carries no pack; drones looked up with `lookup_reads` that carry none retired need
    no query."""
    if _nothing_retired(drones):
        return [None] * len(drones)
    reported = {
        d.pk: (d.organisation_id, s)
        for d in drones
        if d.pk is not None and (s := _reported_serial(d))
    }
    chosen = [d.pk for d in drones if d.pk is not None and d.pk not in reported]
    retired: dict[tuple[int, str], str] = {}
    if reported:
        rows = Organisation.objects.filter(
            pk__in={org for org, _ in reported.values()},
            batteries__serial__in={serial for _, serial in reported.values()},
            batteries__retired=True,
        ).values_list("pk", "batteries__serial", "batteries__retired_reason")
        retired = {(org, serial): reason for org, serial, reason in rows}
    found: dict[int, str | None] = {}
    for pk, key in reported.items():
        reason = retired.get(key)
        found[pk] = None if reason is None else f"battery {key[1]} retired: {reason}"
    if chosen:
        rows = (
            Drone.objects.filter(pk__in=chosen, batteries__retired=True)
            .order_by("pk", "batteries__serial")
            .values_list("pk", "batteries__serial", "batteries__retired_reason")
        )
        for pk, serial, reason in rows:
            found.setdefault(pk, f"battery {serial} retired: {reason}")
    return [None if d.pk is None else found.get(d.pk) for d in drones]


REASONS: list[Reason] = [
    remote_id_failing,
    no_serial_number,
    no_operator_registration,
    no_broadcast,
    wind_above_limit,
    battery_retired,
    maintenance_due,
]

# Reasons that judge many drones at once, in a fixed number of queries however many: each
# gives, in the drones' order, what the reason alone gives each drone, and the reason
# alone is its batch of one. The others, which ask nothing of the database, are asked
# drone by drone.
MANY: dict[Reason, Callable[[Sequence[Drone]], list[str | None]]] = {
    battery_retired: battery_retired_many,
    maintenance_due: maintenance_due_many,
}


def _judged(drones: Sequence[Drone]) -> list[Verdict]:
    """Every reason that keeps each drone on the ground, in REASONS' order."""
    batched = {check: MANY[check](drones) for check in REASONS if check in MANY}
    out = []
    for n, drone in enumerate(drones):
        reasons = [
            reason
            for check in REASONS
            if (reason := batched[check][n] if check in batched else check(drone)) is not None
        ]
        out.append(Verdict(airworthy=not reasons, reasons=reasons))
    return out


def verdict(drone: Drone) -> Verdict:
    """Every reason that keeps the drone on the ground, in REASONS' order."""
    return _judged([drone])[0]


def verdicts(drones: Sequence[Drone]) -> dict[int, Verdict]:
    """`verdict` of each stored drone, by pk, the reasons in MANY read for all of them at
    once (a selection's candidates, a table page)."""
    return {
        d.pk: found for d, found in zip(drones, _judged(drones), strict=True) if d.pk is not None
    }


def refused(drone: Drone) -> tuple[str, list[str]] | None:
    """The sentence a refused arm or mission start gives and its reasons (the ones the
    airworthiness endpoint lists), or None when airworthy."""
    found = verdict(drone)
    if found.airworthy:
        return None
    sentence = f"Drone {drone.drone_id} is not airworthy: " + "; ".join(found.reasons) + "."
    return sentence, list(found.reasons)


def refusal(drone: Drone) -> str | None:
    """The sentence a refused arm or mission start gives, or None when airworthy."""
    found = refused(drone)
    return None if found is None else found[0]

"""Setting Remote ID identities (docs/remote-id.md): a drone's serial number and external
module declaration, an organisation's operator registration and whether it requires
Remote ID. Admins only; each change is recorded in the audit trail (who, when, what) and
the drone gets its identity with its envelope.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from django.db import transaction

from . import envelopes
from .identity import (
    EU_CATEGORIES,
    EU_CLASSES,
    UA_TYPES,
    IdentityError,
    check_eu_declaration,
    declared_name,
    parse_declared,
    parse_operator_id,
    parse_serial_number,
)
from .models import Drone, Organisation
from .signals import identity_changed

# The declared fields, by API name: their model field and the names of their values.
DECLARED = {"ua_type": UA_TYPES, "eu_category": EU_CATEGORIES, "eu_class": EU_CLASSES}
DRONE_FIELDS = ("serial_number", "remote_id_external", *DECLARED)
ORGANISATION_FIELDS = ("operator_id", "require_remote_id")


def drone_identity(drone: Drone) -> dict:
    return {
        "drone_id": drone.drone_id,
        "serial_number": drone.serial_number,
        "remote_id_external": drone.remote_id_external,
        **{field: declared_name(getattr(drone, field), names) for field, names in DECLARED.items()},
    }


def declared_labels(drone: Drone) -> dict[str, str]:
    """What the drone's broadcast declares of it, as its page shows it."""
    labels = {"ua_type": "UA type", "eu_category": "EU category", "eu_class": "EU class"}
    return {
        labels[field]: declared_name(getattr(drone, field), names).replace("_", " ")
        for field, names in DECLARED.items()
    }


def organisation_remote_id(organisation: Organisation) -> dict:
    return {
        "organisation": organisation.slug,
        "operator_id": organisation.operator_id,
        "require_remote_id": organisation.require_remote_id,
    }


def _known(data: Mapping, allowed: tuple[str, ...]) -> None:
    if not isinstance(data, Mapping):
        raise IdentityError("non_field_errors", "must be a JSON object")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise IdentityError(unknown[0], "unknown field")


def _flag(value: Any, field: str) -> bool:
    if not isinstance(value, bool):
        raise IdentityError(field, "must be true or false")
    return value


def _drone_changes(drone: Drone, data: Mapping) -> dict:
    _known(data, DRONE_FIELDS)
    changes: dict[str, Any] = {}
    if "serial_number" in data:
        serial = parse_serial_number(data["serial_number"])
        taken = Drone.objects.filter(serial_number=serial).exclude(pk=drone.pk).exists()
        if serial and taken:
            raise IdentityError("serial_number", "another drone already has this serial number")
        changes["serial_number"] = serial
    if "remote_id_external" in data:
        changes["remote_id_external"] = _flag(data["remote_id_external"], "remote_id_external")
    for field, names in DECLARED.items():
        if field in data:
            changes[field] = parse_declared(data[field], field, names)
    check_eu_declaration(
        changes.get("eu_category", drone.eu_category), changes.get("eu_class", drone.eu_class)
    )
    return {key: value for key, value in changes.items() if getattr(drone, key) != value}


def set_drone_identity(drone: Drone, data: Mapping, user: Any) -> dict:
    """Change the drone's identity; IdentityError names the bad field, nothing changes."""
    changes = _drone_changes(drone, data)
    if changes:
        _store(drone, changes, user, "remote_id.drone", drone.drone_id, drone.organisation_id)
    return drone_identity(drone)


def set_organisation_remote_id(organisation: Organisation, data: Mapping, user: Any) -> dict:
    """Change the operator registration (stored as broadcast: an EU number's 16 public
    characters) or the Remote ID requirement; IdentityError names the bad field."""
    _known(data, ORGANISATION_FIELDS)
    changes: dict[str, Any] = {}
    if "operator_id" in data:
        changes["operator_id"] = parse_operator_id(data["operator_id"])
    if "require_remote_id" in data:
        changes["require_remote_id"] = _flag(data["require_remote_id"], "require_remote_id")
    changes = {k: v for k, v in changes.items() if getattr(organisation, k) != v}
    if changes:
        _store(
            organisation, changes, user, "remote_id.operator", organisation.name, organisation.pk
        )
    return organisation_remote_id(organisation)


def _named(changes: dict) -> dict:
    """The changes as the audit trail shows them: declared numbers by their API names."""
    return {
        key: declared_name(value, DECLARED[key]) if key in DECLARED else value
        for key, value in changes.items()
    }


def _store(
    target: Drone | Organisation,
    changes: dict,
    user: Any,
    action: str,
    name: str,
    organisation_id: int,
) -> None:
    """Write the changes, record them in the audit trail and, once committed, send the
    affected drones their envelope with the new identity."""
    with transaction.atomic():
        type(target).objects.filter(pk=target.pk).update(**changes)
        for key, value in changes.items():
            setattr(target, key, value)
        identity_changed.send(
            type(target),
            organisation_id=organisation_id,
            user=user,
            action=action,
            target=name,
            changed=_named(changes),
        )
        drones = Drone.objects.filter(organisation_id=organisation_id)
        if isinstance(target, Drone):
            drones = drones.filter(pk=target.pk)
        affected = list(drones.select_related("organisation"))
        transaction.on_commit(lambda: envelopes.send_to_drones(affected))

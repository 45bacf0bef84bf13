"""A drone's log collection mode (onboard/collect.py): `always`, `ground_links` or `off`.

Operators and admins set it; the change is recorded in the audit trail (who, when, the
new mode) and, once committed, the drone gets it with its envelope (`log_collection` on
`<id>/envelope/in`), which the agent keeps across restarts and obeys above the gear
folder's collect.json.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from django.db import transaction

from fleet import envelopes
from fleet.models import Drone, LogCollection
from fleet.signals import drone_setting_changed

FIELD = "log_collection"
MODES = tuple(LogCollection.values)


class PolicyError(ValueError):
    """A refused change; `field` names the offending field."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def drone_policy(drone: Drone) -> dict:
    return {"drone_id": drone.drone_id, FIELD: drone.log_collection}


def parse_change(data: Any) -> str:
    """The mode asked for in `{"log_collection": mode}`; PolicyError names the bad field."""
    if not isinstance(data, Mapping):
        raise PolicyError("non_field_errors", "must be a JSON object")
    unknown = sorted(set(data) - {FIELD})
    if unknown:
        raise PolicyError(str(unknown[0]), "unknown field")
    if FIELD not in data:
        raise PolicyError(FIELD, "this field is required")
    mode = data[FIELD]
    if not isinstance(mode, str) or mode not in MODES:
        raise PolicyError(FIELD, f"must be one of {', '.join(MODES)}")
    return mode


def set_drone_policy(drone: Drone, data: Any, user: Any) -> dict:
    """Change the drone's mode; PolicyError names the bad field and nothing changes."""
    mode = parse_change(data)
    if mode != drone.log_collection:
        with transaction.atomic():
            Drone.objects.filter(pk=drone.pk).update(log_collection=mode)
            drone.log_collection = mode
            drone_setting_changed.send(
                Drone,
                organisation_id=drone.organisation_id,
                user=user,
                action=f"drone.{FIELD}",
                target=drone.drone_id,
                changed={FIELD: mode},
            )
            transaction.on_commit(lambda: envelopes.send_to_drones([drone]))
    return drone_policy(drone)

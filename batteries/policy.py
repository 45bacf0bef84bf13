"""Setting an organisation's battery rules and a pack's own figures: checked whole,
refused naming the field, nothing changed on a refusal."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from django.db import transaction

from . import signals
from .fitting import BatteryRefused
from .models import Battery, BatteryPolicy
from .usage import judge, policy_of, refresh

POLICY_FIELDS = ("health_threshold", "cycle_limit")
# No pack is rated for more cycles than this; a larger limit is a typing error.
MAX_CYCLE_LIMIT = 100_000
MAX_RATED_WH = 100_000


def _known(data: Any, allowed: tuple[str, ...]) -> None:
    if not isinstance(data, Mapping):
        raise BatteryRefused("non_field_errors", "must be a JSON object")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise BatteryRefused(unknown[0], "unknown field")


def _number(value: Any, field: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise BatteryRefused(field, "must be a number")
    if not lo <= value <= hi:
        raise BatteryRefused(field, f"must be between {lo:g} and {hi:g}")
    return float(value)


def describe_policy(policy: BatteryPolicy, slug: str) -> dict:
    return {
        "organisation": slug,
        "health_threshold": policy.health_threshold,
        "cycle_limit": policy.cycle_limit,
    }


def _announce(organisation_id: int, user: Any, action: str, target: str, changed: dict) -> None:
    """Tell the audit trail what changed ({field: [old, new]}); nothing when nothing did."""
    if changed:
        signals.changed.send(
            Battery,
            organisation_id=organisation_id,
            user=user,
            action=action,
            target=target,
            changed=changed,
        )


def set_policy(organisation: Any, data: Any, user: Any = None) -> BatteryPolicy:
    """Change the rules and judge every pack of the organisation again."""
    _known(data, POLICY_FIELDS)
    changes: dict[str, float | None] = {}
    if "health_threshold" in data:
        changes["health_threshold"] = _number(data["health_threshold"], "health_threshold", 0, 1)
    if "cycle_limit" in data:
        limit = data["cycle_limit"]
        changes["cycle_limit"] = (
            None if limit is None else _number(limit, "cycle_limit", 0, MAX_CYCLE_LIMIT)
        )
    with transaction.atomic():
        policy, _ = BatteryPolicy.objects.select_for_update().get_or_create(
            organisation=organisation
        )
        before = {key: getattr(policy, key) for key in changes}
        for key, value in changes.items():
            setattr(policy, key, value)
        policy.save()
        _announce(
            organisation.pk,
            user,
            "battery.rules",
            organisation.name,
            {k: [before[k], v] for k, v in changes.items() if before[k] != v},
        )
        for battery in Battery.objects.filter(organisation=organisation):
            judge(battery, policy)
    return policy


def new_battery(organisation: Any, data: Any, user: Any = None) -> Battery:
    """A pack a member names (a flight controller that reports no serial)."""
    _known(data, ("serial", "rated_energy_wh"))
    serial = data.get("serial")
    if not isinstance(serial, str) or not serial.strip() or len(serial.strip()) > 64:
        raise BatteryRefused("serial", "must be a name of 1 to 64 characters")
    serial = serial.strip()
    if Battery.objects.filter(organisation=organisation, serial=serial).exists():
        raise BatteryRefused("serial", "this organisation already has a pack of that name")
    rated = data.get("rated_energy_wh")
    rated = None if rated is None else _number(rated, "rated_energy_wh", 1, MAX_RATED_WH)
    with transaction.atomic():
        battery = Battery.objects.create(
            organisation=organisation, serial=serial, rated_energy_wh=rated
        )
        _announce(
            organisation.pk,
            user,
            "battery.add",
            serial,
            {"serial": [None, serial], "rated_energy_wh": [None, rated]},
        )
    return battery


def set_rating(battery: Battery, data: Any, user: Any = None) -> Battery:
    """Change the pack's rated energy (from its label) and judge it again."""
    _known(data, ("rated_energy_wh",))
    if "rated_energy_wh" in data:
        rated = data["rated_energy_wh"]
        before = battery.rated_energy_wh
        battery.rated_energy_wh = (
            None if rated is None else _number(rated, "rated_energy_wh", 1, MAX_RATED_WH)
        )
        with transaction.atomic():
            Battery.objects.filter(pk=battery.pk).update(rated_energy_wh=battery.rated_energy_wh)
            refresh(battery, policy_of(battery.organisation_id))
            if before != battery.rated_energy_wh:
                _announce(
                    battery.organisation_id,
                    user,
                    "battery.change",
                    battery.serial,
                    {"rated_energy_wh": [before, battery.rated_energy_wh]},
                )
    return battery

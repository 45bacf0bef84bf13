"""What a flight does to its pack: written with the flight's record (records.building
calls `take` in the record's transaction), then the pack's totals, health and
retirement brought up to date."""

from __future__ import annotations

import statistics
from typing import Any

from . import health
from .models import Battery, BatteryFlight, BatteryPolicy


def policy_of(organisation_id: int) -> BatteryPolicy:
    """The organisation's rules (the defaults when it set none), not stored."""
    found = BatteryPolicy.objects.filter(organisation_id=organisation_id).first()
    return found or BatteryPolicy(organisation_id=organisation_id)


def take(record: Any, resistance_ohm: float | None) -> BatteryFlight | None:
    """Count the recorded flight against the pack it names (None: it names none)."""
    if not record.battery:
        return None
    battery = Battery.objects.filter(
        organisation_id=record.organisation_id, serial=record.battery
    ).first()
    if battery is None:
        return None
    drop = health.soc_drop(record.battery_start, record.battery_end)
    use = BatteryFlight.objects.create(
        battery=battery,
        record=record,
        started_at=record.started_at,
        soc_drop=drop,
        cycles=health.flight_cycles(drop, record.energy_wh, battery.rated_energy_wh),
        energy_wh=record.energy_wh,
        capacity_wh=health.capacity_wh(record.energy_wh, drop),
        resistance_ohm=resistance_ohm,
    )
    refresh(battery)
    return use


def retake(old: Any, new: Any) -> BatteryFlight | None:
    """A correction `new` of the record `old`: the flight counts against the pack `new`
    names, with `new`'s figures, and no longer through `old`'s use (kept, as `old` is)."""
    before = BatteryFlight.objects.filter(record=old).select_related("battery").first()
    use = take(new, before.resistance_ohm if before else None)
    if before is not None and (use is None or use.battery_id != before.battery_id):
        refresh(before.battery)
    return use


def refresh(battery: Battery, policy: BatteryPolicy | None = None) -> Battery:
    """The pack's totals, health and retirement from its flights and the rules; a
    corrected record's use no longer counts (its correction's does)."""
    uses = list(
        battery.uses.filter(record__corrected_by__isnull=True).values_list(
            "cycles", "energy_wh", "capacity_wh", "resistance_ohm"
        )
    )  # newest first
    capacities = [c for _, _, c, _ in uses if c is not None]
    resistances = [r for *_, r in uses if r is not None][: health.HEALTH_FLIGHTS]
    battery.flights = len(uses)
    battery.cycles = round(sum(c for c, *_ in uses), 3)
    battery.energy_wh = round(sum(e or 0.0 for _, e, _, _ in uses), 3)
    battery.capacity_wh = (
        round(statistics.median(capacities[: health.HEALTH_FLIGHTS]), 2) if capacities else None
    )
    battery.resistance_ohm = round(statistics.median(resistances), 4) if resistances else None
    battery.health = health.health(capacities, battery.rated_energy_wh)
    return judge(battery, policy)


def judge(battery: Battery, policy: BatteryPolicy | None = None) -> Battery:
    """Apply the organisation's rules to the pack's figures and store the verdict."""
    policy = policy or policy_of(battery.organisation_id)
    battery.retired_reason = health.retirement(
        battery.health, battery.cycles, policy.health_threshold, policy.cycle_limit
    )
    battery.retired = bool(battery.retired_reason)
    Battery.objects.filter(pk=battery.pk).update(
        flights=battery.flights,
        cycles=battery.cycles,
        energy_wh=battery.energy_wh,
        capacity_wh=battery.capacity_wh,
        resistance_ohm=battery.resistance_ohm,
        health=battery.health,
        retired=battery.retired,
        retired_reason=battery.retired_reason,
    )
    return battery

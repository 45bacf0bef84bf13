"""Which pack a drone carries: the one its flight controller names by serial number
(MAVLink SMART_BATTERY_INFO / BATTERY_INFO, reported in the heartbeat and kept in the
drone's `fc.battery_serial`), else the one a member chose on the drone page."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from django.db import IntegrityError, transaction

from fleet.models import Drone

from . import health, signals
from .models import Battery


class BatteryRefused(Exception):
    """A change refused, naming the field; nothing was changed."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field
        self.message = message


def reported_serial(drone: Drone) -> str | None:
    serial = (drone.fc or {}).get("battery_serial")
    return serial if isinstance(serial, str) and serial else None


def rated_from_specs(specs: Any) -> float | None:
    """Rated energy from the gear specs' BATTERY (CAPACITY mAh, CELL_COUNT)."""
    battery = specs.get("BATTERY") if isinstance(specs, dict) else None
    if not isinstance(battery, dict):
        return None
    try:
        return health.rated_energy_wh(
            float(battery.get("CAPACITY")), int(battery.get("CELL_COUNT"))
        )
    except (TypeError, ValueError):
        return None


def carried(drone: Drone) -> Battery | None:
    """The pack the drone carries now; a reported serial is attached to the drone (and
    registered on first sight)."""
    serial = reported_serial(drone)
    if serial is None:
        return Battery.objects.filter(drone=drone).first()
    battery = _registered(drone, serial)
    if battery.drone_id != drone.pk:
        _attach(battery, drone)
    return battery


def _registered(drone: Drone, serial: str) -> Battery:
    defaults = {"reported": True, "rated_energy_wh": rated_from_specs(drone.specs)}
    try:
        with transaction.atomic():
            battery, _ = Battery.objects.get_or_create(
                organisation_id=drone.organisation_id, serial=serial, defaults=defaults
            )
    except IntegrityError:  # registered meanwhile by another process
        battery = Battery.objects.get(organisation_id=drone.organisation_id, serial=serial)
    return battery


def _attach(battery: Battery, drone: Drone | None) -> None:
    with transaction.atomic():
        if drone is not None:
            Battery.objects.filter(drone=drone).exclude(pk=battery.pk).update(drone=None)
        Battery.objects.filter(pk=battery.pk).update(drone=drone)
        battery.drone = drone


def sync(drones: Iterable[Drone]) -> None:
    """Attach the packs these drones report (a list or page shows them where they are)."""
    for drone in drones:
        if reported_serial(drone) is not None:
            carried(drone)


def choose(drone: Drone, battery_id: Any, user: Any = None) -> Battery | None:
    """A member's choice of the pack the drone carries (None: none); BatteryRefused
    names the field when the choice makes no sense. The audit trail hears the old and
    the new pack."""
    chosen = _chosen(drone, battery_id)
    with transaction.atomic():
        before = Battery.objects.filter(drone=drone).first()
        if chosen is None:
            Battery.objects.filter(drone=drone).update(drone=None)
        else:
            _attach(chosen, drone)
        old, new = _serial(before), _serial(chosen)
        if old != new:
            signals.changed.send(
                Battery,
                organisation_id=drone.organisation_id,
                user=user,
                action="battery.fit",
                target=drone.drone_id,
                changed={"battery": [old, new]},
            )
    return chosen


def _serial(battery: Battery | None) -> str | None:
    return None if battery is None else battery.serial


def _chosen(drone: Drone, battery_id: Any) -> Battery | None:
    """The pack a member names for the drone (None: none), checked; nothing changed."""
    serial = reported_serial(drone)
    if serial is not None:
        raise BatteryRefused(
            "battery", f"the flight controller reports the pack fitted (serial {serial})"
        )
    if battery_id in (None, ""):
        return None
    try:
        pk = int(battery_id)
    except (TypeError, ValueError):
        raise BatteryRefused("battery", "must be a battery id") from None
    battery = Battery.objects.filter(organisation_id=drone.organisation_id, pk=pk).first()
    if battery is None:
        raise BatteryRefused("battery", f"no battery {pk} in this organisation")
    if battery.reported:
        raise BatteryRefused("battery", "this pack is named by a flight controller")
    return battery

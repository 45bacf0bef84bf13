"""Batteries as assets: each pack an organisation flies, what it has done (cycles, energy,
flights) and what its flights say of its health; and the organisation's rules for
retiring a pack (docs/batteries.md)."""

from __future__ import annotations

from typing import Any

from django.db import models
from django.db.models import Q
from django.utils import timezone

from fleet.tenancy import reach

# A pack whose capacity is below 80 % of its rating is at the end of its life
# [IEEE 1188-2005] (the replacement criterion for stationary batteries, the usual one for
# lithium packs too); an organisation sets its own threshold.
DEFAULT_HEALTH_THRESHOLD = 0.8


class BatteryPolicy(models.Model):
    """An organisation's retirement rules; without a row, the defaults hold."""

    organisation = models.OneToOneField(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="battery_policy"
    )
    # Health (estimated capacity / rated capacity, 0..1) under which a pack is retired.
    health_threshold = models.FloatField(default=DEFAULT_HEALTH_THRESHOLD)
    # Equivalent full cycles above which a pack is retired; null: no limit.
    cycle_limit = models.FloatField(null=True, blank=True)

    def __str__(self) -> str:
        return f"battery rules of {self.organisation}"


class BatteryQuerySet(models.QuerySet):
    def for_user(self, user: Any) -> BatteryQuerySet:
        """Only packs of organisations the user belongs to: the isolation rule."""
        if not user.is_authenticated:
            return self.none()
        return self.filter(reach(user))


class Battery(models.Model):
    """One pack, named by the serial number its flight controller reports or, for a
    flight controller that reports none, by the name a member gives it."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="batteries"
    )
    serial = models.CharField(max_length=64)
    # True: the serial came from the flight controller (SMART_BATTERY_INFO / BATTERY_INFO).
    reported = models.BooleanField(default=False)
    # The drone carrying the pack now (at most one pack per drone).
    drone = models.ForeignKey(
        "fleet.Drone", null=True, blank=True, on_delete=models.SET_NULL, related_name="batteries"
    )
    rated_energy_wh = models.FloatField(null=True, blank=True)
    in_service_since = models.DateTimeField(default=timezone.now)

    # What its flights add up to (batteries.usage keeps them current).
    flights = models.PositiveIntegerField(default=0)
    cycles = models.FloatField(default=0.0)
    energy_wh = models.FloatField(default=0.0)
    capacity_wh = models.FloatField(null=True, blank=True)
    resistance_ohm = models.FloatField(null=True, blank=True)
    health = models.FloatField(null=True, blank=True)
    retired = models.BooleanField(default=False)
    retired_reason = models.CharField(max_length=200, blank=True)

    objects = BatteryQuerySet.as_manager()

    class Meta:
        ordering = ["serial"]
        constraints = [
            models.UniqueConstraint(
                fields=["organisation", "serial"], name="batteries_one_serial_per_organisation"
            ),
            models.UniqueConstraint(
                fields=["drone"], condition=Q(drone__isnull=False), name="batteries_one_per_drone"
            ),
        ]

    def __str__(self) -> str:
        return self.serial

    @property
    def age_days(self) -> float:
        return (timezone.now() - self.in_service_since).total_seconds() / 86400.0


APPEND_ONLY = "a pack's flights are append-only: each is what one recorded flight did to it"


class BatteryFlightQuerySet(models.QuerySet):
    def update(self, **kwargs: object) -> int:
        raise PermissionError(APPEND_ONLY)

    def delete(self) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)


class BatteryFlight(models.Model):
    """What one flight did to one pack: written with the flight's record, never changed
    (like the record: a correction is a new record)."""

    battery = models.ForeignKey(Battery, on_delete=models.CASCADE, related_name="uses")
    record = models.OneToOneField(
        "records.FlightRecord", on_delete=models.CASCADE, related_name="battery_use"
    )
    started_at = models.DateTimeField()
    soc_drop = models.FloatField(null=True, blank=True)
    cycles = models.FloatField(default=0.0)
    energy_wh = models.FloatField(null=True, blank=True)
    capacity_wh = models.FloatField(null=True, blank=True)
    resistance_ohm = models.FloatField(null=True, blank=True)

    objects = BatteryFlightQuerySet.as_manager()

    class Meta:
        ordering = ["-started_at"]

    def __str__(self) -> str:
        return f"{self.battery} {self.started_at:%Y-%m-%d %H:%M}"

    def save(self, *args: object, **kwargs: object) -> None:
        if self.pk is not None:
            raise PermissionError(APPEND_ONLY)
        super().save(*args, **kwargs)  # type: ignore[arg-type]

    def delete(self, *args: object, **kwargs: object) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)

"""Flight records: one per flight (arm to disarm), written once when the flight closes and
never changed; a correction is a new record naming the one it corrects. A flight still
in the air is an `OpenFlight`, the working state the record is built from."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.db import models
from django.db.models import Q
from django.utils import timezone

from fleet.tenancy import reach

APPEND_ONLY = "flight records are append-only: correct one with a new record"


class Origin(models.TextChoices):
    """Who started the flight."""

    COMMAND = "command", "Operator's command"
    MISSION = "mission", "Operator's mission"
    PLATFORM = "platform", "Platform (automatic)"
    UNKNOWN = "unknown", "Not through the ground"


class EnergyMethod(models.TextChoices):
    VOLTAGE_CURRENT = "voltage_current", "Voltage × current samples"
    CAPACITY_CHARGE = "capacity_charge", "Capacity × state-of-charge drop"
    UNKNOWN = "", "Not known"


class OpenFlight(models.Model):
    """A drone seen armed and not yet recorded: opened on the heartbeat that shows it
    armed, marked disarmed on the one that shows it disarmed, then turned into a
    FlightRecord (records.building) and deleted."""

    drone = models.ForeignKey("fleet.Drone", on_delete=models.CASCADE, related_name="+")
    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="+"
    )
    armed_at = models.DateTimeField()
    disarmed_at = models.DateTimeField(null=True, blank=True)
    # What the heartbeat said at arming and disarming.
    mission = models.JSONField(null=True, blank=True)
    start = models.JSONField(default=dict, blank=True)
    end = models.JSONField(default=dict, blank=True)

    class Meta:
        ordering = ["armed_at"]
        constraints = [
            # One flight in the air per drone.
            models.UniqueConstraint(
                fields=["drone"],
                condition=Q(disarmed_at__isnull=True),
                name="records_one_open_flight_per_drone",
            )
        ]

    def __str__(self) -> str:
        return f"{self.drone} armed at {self.armed_at:%Y-%m-%d %H:%M:%S}"


class FlightRecordQuerySet(models.QuerySet):
    def for_user(self, user: Any) -> FlightRecordQuerySet:
        """Only records of organisations the user belongs to: the isolation rule."""
        if not user.is_authenticated:
            return self.none()
        return self.filter(reach(user))

    def current(self) -> FlightRecordQuerySet:
        """Records no correction replaces: one per flight, its latest version."""
        return self.filter(corrected_by__isnull=True)

    def update(self, **kwargs: object) -> int:
        raise PermissionError(APPEND_ONLY)

    def delete(self) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)


class FlightRecord(models.Model):
    """One flight of one drone, arm to disarm, with the figures a logbook keeps."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="flight_records"
    )
    drone = models.ForeignKey(
        "fleet.Drone", null=True, on_delete=models.SET_NULL, related_name="flight_records"
    )
    # Kept when the drone is removed later.
    drone_ident = models.CharField(max_length=64)
    origin = models.CharField(max_length=10, choices=Origin.choices)
    pilot = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    pilot_name = models.CharField(max_length=150, blank=True)
    mission = models.ForeignKey(
        "missions.Mission", null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    mission_name = models.CharField(max_length=200, blank=True)
    assignment_id = models.UUIDField(null=True, blank=True)

    started_at = models.DateTimeField()
    ended_at = models.DateTimeField()
    takeoff_at = models.DateTimeField(null=True, blank=True)
    landing_at = models.DateTimeField(null=True, blank=True)
    takeoff_position = models.JSONField(null=True, blank=True)
    landing_position = models.JSONField(null=True, blank=True)
    home = models.JSONField(null=True, blank=True)

    duration_s = models.FloatField()
    airborne_s = models.FloatField(null=True, blank=True)
    distance_m = models.FloatField(null=True, blank=True)
    max_height_m = models.FloatField(null=True, blank=True)
    max_speed_ms = models.FloatField(null=True, blank=True)
    max_distance_m = models.FloatField(null=True, blank=True)

    battery_start = models.FloatField(null=True, blank=True)
    battery_end = models.FloatField(null=True, blank=True)
    voltage_start = models.FloatField(null=True, blank=True)
    voltage_end = models.FloatField(null=True, blank=True)
    energy_wh = models.FloatField(null=True, blank=True)
    energy_method = models.CharField(
        max_length=16, choices=EnergyMethod.choices, blank=True, default=""
    )
    # The battery pack flown, once packs are tracked on their own; null (not "") until
    # then, so the API says "not known" rather than naming an empty pack.
    battery = models.CharField(max_length=64, null=True, blank=True)  # noqa: DJ001

    events = models.JSONField(default=list, blank=True)
    # A thinned track, [seconds from arming, north m, east m, height m] from home.
    track = models.JSONField(default=list, blank=True)
    samples = models.PositiveIntegerField(default=0)

    corrects = models.OneToOneField(
        "self", null=True, blank=True, on_delete=models.PROTECT, related_name="corrected_by"
    )
    correction_reason = models.CharField(max_length=500, blank=True)
    recorded_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    recorded_at = models.DateTimeField(default=timezone.now)

    objects = FlightRecordQuerySet.as_manager()

    class Meta:
        ordering = ["-started_at", "-id"]
        indexes = [
            models.Index(fields=["organisation", "-started_at"]),
            models.Index(fields=["drone", "-started_at"]),
            models.Index(fields=["pilot", "-started_at"]),
        ]
        constraints = [
            # A flight closed twice (a task run again, two workers) is recorded once.
            models.UniqueConstraint(
                fields=["drone_ident", "started_at"],
                condition=Q(corrects__isnull=True),
                name="records_one_record_per_flight",
            )
        ]

    def __str__(self) -> str:
        return f"{self.drone_ident} {self.started_at:%Y-%m-%d %H:%M:%S} ({self.duration_s:.0f} s)"

    def save(self, *args: object, **kwargs: object) -> None:
        if self.pk is not None:
            raise PermissionError(APPEND_ONLY)
        super().save(*args, **kwargs)  # type: ignore[arg-type]

    def delete(self, *args: object, **kwargs: object) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)

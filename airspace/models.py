"""Airspace reservations: what each flight the platform sent holds in space and time, and
the separation minima each organisation keeps (airspace/corridors.py, airspace/index.py)."""

from __future__ import annotations

from django.core.validators import MinValueValidator
from django.db import models

from fleet.models import Drone, Organisation


class SeparationMinima(models.Model):
    """An organisation's own minima; without a row, AIRSPACE_HORIZONTAL_MIN_M and
    AIRSPACE_VERTICAL_MIN_M apply."""

    organisation = models.OneToOneField(
        Organisation, on_delete=models.CASCADE, related_name="separation_minima"
    )
    horizontal_m = models.FloatField(
        validators=[MinValueValidator(0.0)], help_text="Metres between corridors' edges."
    )
    vertical_m = models.FloatField(
        validators=[MinValueValidator(0.0)], help_text="Metres between altitude bands."
    )

    class Meta:
        verbose_name_plural = "separation minima"

    def __str__(self) -> str:
        return f"{self.organisation}: {self.horizontal_m:g} m / {self.vertical_m:g} m"


class Reservation(models.Model):
    """The corridors one flight holds: a mission's assignment, or a drone's last
    navigation command. Active while `ended_at` is empty."""

    class Kind(models.TextChoices):
        MISSION = "mission", "Mission"
        COMMAND = "command", "Command"

    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="reservations"
    )
    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="reservations")
    kind = models.CharField(max_length=10, choices=Kind.choices)
    # A lazy reference: missions imports airspace, not the other way round.
    assignment = models.ForeignKey(
        "missions.Assignment",
        null=True,
        blank=True,
        on_delete=models.CASCADE,
        related_name="reservations",
    )
    command = models.CharField(max_length=40, blank=True)
    created_at = models.DateTimeField(auto_now_add=True)
    # Each leg: [lat0, lon0, lat1, lon1, low m, high m, t0, t1] (times: seconds since the epoch).
    legs = models.JSONField(default=list)
    starts_at = models.DateTimeField()
    ends_at = models.DateTimeField()
    # Seen on the ground once seen in the air (`flown`), or after `airborne_by`, the drone
    # has landed.
    airborne_by = models.DateTimeField()
    flown = models.BooleanField(default=False)
    radius_m = models.FloatField()
    horizontal_min_m = models.FloatField()
    vertical_min_m = models.FloatField()
    min_lat = models.FloatField()
    max_lat = models.FloatField()
    min_lon = models.FloatField()
    max_lon = models.FloatField()
    ended_at = models.DateTimeField(null=True, blank=True)
    end_reason = models.CharField(max_length=80, blank=True)

    class Meta:
        indexes = [
            models.Index(
                fields=["organisation", "ends_at"],
                name="airspace_active",
                condition=models.Q(ended_at__isnull=True),
            ),
            models.Index(fields=["drone", "ended_at"]),
        ]

    def __str__(self) -> str:
        return f"{self.drone} {self.kind} {self.starts_at:%Y-%m-%d %H:%M:%S}"


class LandingSlot(models.Model):
    """A drone's place in the landing queue over its home (airspace/landing.py): it holds
    over home at `layer_m` until its turn, then lands. Active while `ended_at` is empty."""

    class State(models.TextChoices):
        HOLDING = "holding", "Holding"
        LANDING = "landing", "Landing"

    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="landing_slots"
    )
    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="landing_slots")
    # The drone's home: drones whose homes are within the horizontal minimum share a site.
    site_lat = models.FloatField()
    site_lon = models.FloatField()
    layer_m = models.FloatField(help_text="Holding height above home.")
    state = models.CharField(max_length=10, choices=State.choices)
    joined_at = models.DateTimeField(auto_now_add=True)
    landing_at = models.DateTimeField(null=True, blank=True)
    ended_at = models.DateTimeField(null=True, blank=True)
    end_reason = models.CharField(max_length=80, blank=True)
    # Its hold (a `navigate` over home at the layer), kept to until its turn: when it was
    # last sent, the request the queue sent it under (whose reply a later pass reads),
    # when the drone accepted it, how often the queue sent it again, and the start of the
    # current watch of the drone's way to it with its distance from it then.
    hold_sent_at = models.DateTimeField(null=True, blank=True)
    hold_request = models.CharField(max_length=64, blank=True, default="", db_default="")
    hold_accepted_at = models.DateTimeField(null=True, blank=True)
    hold_resends = models.PositiveSmallIntegerField(default=0, db_default=0)
    watched_at = models.DateTimeField(null=True, blank=True)
    watched_m = models.FloatField(null=True, blank=True)

    class Meta:
        indexes = [
            models.Index(
                fields=["organisation", "joined_at"],
                name="airspace_landing_active",
                condition=models.Q(ended_at__isnull=True),
            ),
        ]

    def __str__(self) -> str:
        return f"{self.drone} {self.state} at {self.layer_m:g} m"

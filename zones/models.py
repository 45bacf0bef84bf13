"""Published UAS geographical zones and the authorisations recorded to fly in them.

A zone is what one publisher's file says about one volume of airspace: its shapes
(polygons and circles, WGS 84), one altitude band with each limit's reference, when it
applies and what it restricts. Each limit is kept in metres with the reference it was
published against; how a band is placed relative to a drone's home is zones/bands.py.
"""

from __future__ import annotations

from django.conf import settings
from django.db import models
from django.utils import timezone


class Restriction(models.TextChoices):
    PROHIBITED = "prohibited", "Prohibited"
    AUTHORISATION_REQUIRED = "authorisation_required", "Authorisation required"
    CONDITIONAL = "conditional", "Conditional"


class Reference(models.TextChoices):
    """What a limit is measured from (ED-269 vertical references, and the home)."""

    AGL = "AGL", "Above ground level"
    AMSL = "AMSL", "Above mean sea level"
    WGS84 = "WGS84", "Above the WGS 84 ellipsoid"
    HOME = "HOME", "Above home"


class Zone(models.Model):
    # None: site-wide (imported for every organisation).
    organisation = models.ForeignKey(
        "fleet.Organisation",
        null=True,
        blank=True,
        on_delete=models.CASCADE,
        related_name="published_zones",
    )
    identifier = models.CharField(max_length=120)
    # An ED-269 zone may have several volumes, each with its own band: one row each.
    part = models.PositiveSmallIntegerField(default=0)
    name = models.CharField(max_length=200)
    restriction = models.CharField(max_length=32, choices=Restriction.choices)
    # [{"type": "polygon", "points": [[lat, lon], ...]} | {"type": "circle",
    #   "center": [lat, lon], "radius": metres}]
    shapes = models.JSONField()
    lower_m = models.FloatField()
    lower_ref = models.CharField(max_length=8, choices=Reference.choices)
    upper_m = models.FloatField()
    upper_ref = models.CharField(max_length=8, choices=Reference.choices)
    # [] = permanent; else periods {"start", "end" (ISO 8601 or null), "schedule":
    # [{"days": ["MON", ...], "start": "HH:MM", "end": "HH:MM"}] (UTC)}.
    applicability = models.JSONField(default=list, blank=True)
    message = models.TextField(blank=True)
    source = models.CharField(max_length=200)
    file_format = models.CharField(max_length=16)
    # The shapes' bounding box, so a leg's candidates are found by the database.
    min_lat = models.FloatField()
    min_lon = models.FloatField()
    max_lat = models.FloatField()
    max_lon = models.FloatField()
    imported_at = models.DateTimeField(default=timezone.now)

    class Meta:
        ordering = ["identifier", "part"]
        constraints = [
            models.UniqueConstraint(
                fields=["organisation", "identifier", "part"],
                name="zone_identifier_per_scope",
                nulls_distinct=False,
            )
        ]
        indexes = [models.Index(fields=["min_lat", "max_lat", "min_lon", "max_lon"])]

    def __str__(self) -> str:
        return f"{self.name} ({self.identifier})"


class Authorisation(models.Model):
    """Permission, issued outside Skyhive, for one organisation to fly in one zone."""

    zone = models.ForeignKey(Zone, on_delete=models.CASCADE, related_name="authorisations")
    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="zone_authorisations"
    )
    # Who issued it (the zone's authority, a person there) and its reference.
    issued_by = models.CharField(max_length=200)
    reference = models.CharField(max_length=200)
    expires_at = models.DateTimeField()
    recorded_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, on_delete=models.SET_NULL, related_name="+"
    )
    recorded_at = models.DateTimeField(default=timezone.now)

    class Meta:
        ordering = ["-recorded_at"]
        indexes = [models.Index(fields=["organisation", "zone", "expires_at"])]

    def __str__(self) -> str:
        return f"{self.reference} for {self.zone_id} until {self.expires_at:%Y-%m-%d %H:%M}"

"""Maintenance: schedules (per drone or per gear model) that fall due by flight hours,
flights or calendar days, service bulletins an admin issues to every drone of a model, and
each drone's maintenance log of sign-offs, append-only like the audit trail."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.db import models
from django.db.models import Q
from django.utils import timezone

from fleet.tenancy import reach

APPEND_ONLY = "the maintenance log is append-only: a sign-off is never changed or removed"


class OrganisationQuerySet(models.QuerySet):
    def for_user(self, user: Any) -> OrganisationQuerySet:
        """Only rows of organisations the user belongs to: the isolation rule."""
        if not user.is_authenticated:
            return self.none()
        return self.filter(reach(user))


class Schedule(models.Model):
    """A task due every so many flight hours, flights (arm/disarm cycles) or days, counted
    from its last sign-off on the drone; for one drone, or every drone of a gear model."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="maintenance_schedules"
    )
    name = models.CharField(max_length=120)
    drone = models.ForeignKey(
        "fleet.Drone",
        null=True,
        blank=True,
        on_delete=models.CASCADE,
        related_name="maintenance_schedules",
    )
    model = models.CharField(max_length=120, blank=True)
    every_hours = models.FloatField(null=True, blank=True)
    every_flights = models.PositiveIntegerField(null=True, blank=True)
    every_days = models.PositiveIntegerField(null=True, blank=True)
    notes = models.TextField(blank=True)
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    created_at = models.DateTimeField(default=timezone.now)
    updated_at = models.DateTimeField(default=timezone.now)

    objects = OrganisationQuerySet.as_manager()

    class Meta:
        ordering = ["name", "id"]
        constraints = [
            models.CheckConstraint(
                condition=(Q(drone__isnull=False) & Q(model=""))
                | (Q(drone__isnull=True) & ~Q(model="")),
                name="maintenance_schedule_one_target",
            ),
            models.CheckConstraint(
                condition=Q(every_hours__isnull=False)
                | Q(every_flights__isnull=False)
                | Q(every_days__isnull=False),
                name="maintenance_schedule_has_trigger",
            ),
            models.CheckConstraint(
                condition=Q(every_hours__isnull=True) | Q(every_hours__gt=0),
                name="maintenance_schedule_hours_positive",
            ),
        ]

    def __str__(self) -> str:
        return self.name

    @property
    def target(self) -> str:
        return self.drone.drone_id if self.drone_id else f"model {self.model}"


class Bulletin(models.Model):
    """A service bulletin: every drone of the model has it open until it is signed off for
    that drone; or a finding on one drone (an admin's, or the platform's from a `source`
    such as a flight-log figure drifting), open until signed off. Never edited."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="maintenance_bulletins"
    )
    model = models.CharField(max_length=120, blank=True)
    drone = models.ForeignKey(
        "fleet.Drone",
        null=True,
        blank=True,
        on_delete=models.CASCADE,
        related_name="maintenance_findings",
    )
    # What opened a finding: the same happening opens one.
    source = models.CharField(max_length=200, blank=True)
    title = models.CharField(max_length=200)
    text = models.TextField()
    issued_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    issued_by_name = models.CharField(max_length=150, blank=True)
    issued_at = models.DateTimeField(default=timezone.now)

    objects = OrganisationQuerySet.as_manager()

    class Meta:
        ordering = ["-issued_at", "-id"]
        constraints = [
            models.CheckConstraint(
                condition=(Q(drone__isnull=False) & Q(model=""))
                | (Q(drone__isnull=True) & ~Q(model="")),
                name="maintenance_bulletin_one_target",
            ),
            models.UniqueConstraint(
                fields=["organisation", "source"],
                condition=~Q(source=""),
                name="maintenance_finding_once_per_source",
            ),
        ]

    def __str__(self) -> str:
        return self.title


class LogQuerySet(OrganisationQuerySet):
    def update(self, **kwargs: object) -> int:
        raise PermissionError(APPEND_ONLY)

    def delete(self) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)


class LogEntry(models.Model):
    """One sign-off in a drone's maintenance log: which task, who, when, what was done and
    which parts were fitted, with the drone's usage at that moment."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="maintenance_log"
    )
    drone = models.ForeignKey(
        "fleet.Drone", null=True, on_delete=models.SET_NULL, related_name="maintenance_log"
    )
    # Kept when the drone, the schedule or the signer is removed later.
    drone_ident = models.CharField(max_length=64)
    schedule = models.ForeignKey(
        Schedule, null=True, blank=True, on_delete=models.SET_NULL, related_name="sign_offs"
    )
    bulletin = models.ForeignKey(
        Bulletin, null=True, blank=True, on_delete=models.PROTECT, related_name="sign_offs"
    )
    item_name = models.CharField(max_length=200)
    signed_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    signed_by_name = models.CharField(max_length=150)
    signed_at = models.DateTimeField(default=timezone.now)
    notes = models.TextField()
    parts = models.JSONField(default=list, blank=True)
    # The item's measures when signed off: [{"trigger", "used", "limit"}, ...].
    usage = models.JSONField(default=list, blank=True)

    objects = LogQuerySet.as_manager()

    class Meta:
        ordering = ["-signed_at", "-id"]
        indexes = [models.Index(fields=["drone", "schedule", "-signed_at"])]
        constraints = [
            # A bulletin is complied with once per drone.
            models.UniqueConstraint(
                fields=["drone_ident", "bulletin"],
                condition=Q(bulletin__isnull=False),
                name="maintenance_bulletin_signed_once",
            )
        ]

    def __str__(self) -> str:
        return f"{self.drone_ident} {self.item_name} signed {self.signed_at:%Y-%m-%d %H:%M}"

    def save(self, *args: object, **kwargs: object) -> None:
        if self.pk is not None:
            raise PermissionError(APPEND_ONLY)
        super().save(*args, **kwargs)  # type: ignore[arg-type]

    def delete(self, *args: object, **kwargs: object) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)

"""Uploaded flight logs: who uploaded what, for which organisation, and how far processing got.

The parsed data itself lives on disk in the core's columnar store (`store.py`), one folder
per log under `settings.LOGS_DIR`; a row is `ready` only once that store is in place.
"""

from __future__ import annotations

import uuid
from pathlib import Path

from django.conf import settings
from django.core.exceptions import SuspiciousFileOperation
from django.db import models
from django.urls import reverse
from django.utils import timezone
from django.utils.text import get_valid_filename

from fleet.models import Organisation
from fleet.tenancy import reach


class LogStatus(models.TextChoices):
    PROCESSING = "processing", "Processing"
    READY = "ready", "Ready"
    FAILED = "failed", "Failed"


class FlightLogQuerySet(models.QuerySet):
    def for_user(self, user) -> FlightLogQuerySet:  # type: ignore[no-untyped-def]
        """Only logs of organisations the user belongs to: the isolation rule."""
        if not user.is_authenticated:
            return self.none()
        return self.filter(reach(user))

    def search(self, query: str) -> FlightLogQuerySet:
        query = query.strip()
        if not query:
            return self
        return self.filter(
            models.Q(name__icontains=query)
            | models.Q(format__icontains=query)
            | models.Q(owner__username__icontains=query)
        )


class FlightLog(models.Model):
    # A UUID, not a counter: the page URL is the shareable link, and ids must not be
    # guessable or collide between databases sharing one Redis (progress groups).
    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="flight_logs"
    )
    owner = models.ForeignKey(
        settings.AUTH_USER_MODEL,
        on_delete=models.SET_NULL,
        null=True,
        blank=True,
        related_name="flight_logs",
    )
    name = models.CharField(max_length=255)
    size = models.BigIntegerField(default=0)
    status = models.CharField(
        max_length=16, choices=LogStatus.choices, default=LogStatus.PROCESSING
    )
    progress = models.FloatField(default=0.0)
    error = models.TextField(blank=True)
    format = models.CharField(max_length=32, blank=True)
    series_count = models.PositiveIntegerField(default=0)
    start_s = models.FloatField(null=True, blank=True)
    end_s = models.FloatField(null=True, blank=True)
    created_at = models.DateTimeField(auto_now_add=True)
    processed_at = models.DateTimeField(null=True, blank=True)
    # Import attempts (logs/attempts.py): how many deliveries started the import, the
    # delivery holding it, its last sign of life, and when the import was last queued.
    attempts = models.PositiveSmallIntegerField(default=0)
    import_task = models.CharField(max_length=64, blank=True)
    heartbeat_at = models.DateTimeField(null=True, blank=True)
    queued_at = models.DateTimeField(default=timezone.now)
    # The drone that flew it (its trends: logs/trends.py), and when it flew; a log with
    # no flight time is placed in a drone's history by when it was uploaded.
    drone = models.ForeignKey(
        "fleet.Drone",
        null=True,
        blank=True,
        on_delete=models.SET_NULL,
        related_name="flight_logs",
    )
    flown_at = models.DateTimeField(null=True, blank=True)

    objects = FlightLogQuerySet.as_manager()

    class Meta:
        ordering = ["-created_at"]
        indexes = [models.Index(fields=["organisation", "-created_at"], name="log_org_recent")]

    def __str__(self) -> str:
        return self.name

    def get_absolute_url(self) -> str:
        return reverse("logs:detail", args=[self.pk])

    @property
    def directory(self) -> Path:
        return Path(settings.LOGS_DIR) / str(self.organisation_id) / str(self.pk)

    @property
    def upload_path(self) -> Path:
        """The file as uploaded, under its own name: importers fall back on the suffix and
        name the file in their error messages."""
        try:
            name = get_valid_filename(self.name)[-120:]
        except SuspiciousFileOperation:
            name = "log"
        return self.directory / "upload" / name

    @property
    def store_path(self) -> Path:
        return self.directory / "store"

    @property
    def group_name(self) -> str:
        """The Channels group the log's page listens on for processing progress."""
        return f"flightlog-{self.pk}"

    @property
    def duration_s(self) -> float | None:
        if self.start_s is None or self.end_s is None:
            return None
        return self.end_s - self.start_s


class LogFigure(models.Model):
    """One check's figure of one log, copied from its health report so a drone's or the
    fleet's trend is one indexed query rather than a file per log (logs/trends.py)."""

    log = models.ForeignKey(FlightLog, on_delete=models.CASCADE, related_name="figures")
    name = models.CharField(max_length=32)
    status = models.CharField(max_length=12)
    value = models.FloatField(null=True, blank=True)
    unit = models.CharField(max_length=16, blank=True)

    class Meta:
        constraints = [
            models.UniqueConstraint(fields=["log", "name"], name="log_figure_one_per_check")
        ]
        indexes = [models.Index(fields=["name", "log"], name="log_figure_name")]

    def __str__(self) -> str:
        return f"{self.name} of {self.log_id}: {self.value}"


class ParameterReference(models.Model):
    """An organisation's reference parameter set for one drone model: the autopilot and
    the airframe id its logs record (PX4 SYS_AUTOSTART, ArduPilot FRAME_CLASS; "" for
    a flight controller that records none), kept from a log chosen by an operator."""

    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="parameter_references"
    )
    autopilot = models.CharField(max_length=16)
    airframe = models.CharField(max_length=32, blank=True)
    parameters = models.JSONField(default=dict)
    source_log = models.ForeignKey(
        FlightLog, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    source_name = models.CharField(max_length=255, blank=True)
    saved_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    saved_at = models.DateTimeField(default=timezone.now)

    class Meta:
        constraints = [
            models.UniqueConstraint(
                fields=["organisation", "autopilot", "airframe"],
                name="parameter_reference_one_per_model",
            )
        ]

    def __str__(self) -> str:
        return f"{self.autopilot} airframe {self.airframe or '-'} of {self.organisation}"


class CollectedLogKind(models.TextChoices):
    ONBOARD = "onboard", "Onboard recording"
    FLIGHT_CONTROLLER = "fc", "Flight controller's log"


class CollectedLog(models.Model):
    """A log a drone uploads by itself after landing (logs/collection.py): received in
    chunks at increasing offsets, stored once per drone, kind and content (its SHA-256),
    and a FlightLog once every byte is in and the hash matches."""

    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    organisation = models.ForeignKey(Organisation, on_delete=models.CASCADE, related_name="+")
    drone = models.ForeignKey(
        "fleet.Drone", on_delete=models.CASCADE, related_name="collected_logs"
    )
    kind = models.CharField(max_length=8, choices=CollectedLogKind.choices)
    name = models.CharField(max_length=255)
    size = models.BigIntegerField()
    sha256 = models.CharField(max_length=64)
    received = models.BigIntegerField(default=0)
    # The flight on the drone's clock: armed and disarmed, as the agent saw them.
    flight_started_at = models.DateTimeField()
    flight_ended_at = models.DateTimeField()
    log = models.OneToOneField(
        FlightLog, null=True, blank=True, on_delete=models.SET_NULL, related_name="collected"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    completed_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["flight_started_at", "kind"]
        constraints = [
            # The idempotency key: one drone's log of one kind with these bytes, once.
            models.UniqueConstraint(fields=["drone", "kind", "sha256"], name="logs_collected_once")
        ]
        indexes = [models.Index(fields=["drone", "flight_started_at"], name="log_collected_flight")]

    def __str__(self) -> str:
        return f"{self.name} ({self.kind})"

    @property
    def part_path(self) -> Path:
        """The bytes received so far, until the log is complete."""
        return Path(settings.LOGS_DIR) / "collecting" / f"{self.pk}.part"

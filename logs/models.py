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

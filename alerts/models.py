"""Alerts an operator cannot miss, and their delivery to each of the organisation's
recipients (e-mail addresses and webhook URLs), once each."""

from __future__ import annotations

import uuid

from django.db import models
from django.utils import timezone


class Alert(models.Model):
    class Kind(models.TextChoices):
        CRITICAL_ALARM = "critical_alarm", "Critical alarm"
        REPLACEMENT = "replacement", "Drone replaced"
        DRONE_LOST = "drone_lost", "Drone lost"
        MISSION_COMPLETED = "mission_completed", "Mission completed"
        MISSION_FAILED = "mission_failed", "Mission failed"
        REMOTE_ID = "remote_id", "Remote ID failing"
        LOG_TREND = "log_trend", "Flight log figure drifting"
        WIND = "wind", "Wind above a drone's limit"
        MAINTENANCE = "maintenance", "Maintenance due"

    class Severity(models.TextChoices):
        CRITICAL = "critical", "Critical"
        WARNING = "warning", "Warning"
        INFO = "info", "Information"

    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="alerts"
    )
    kind = models.CharField(max_length=20, choices=Kind.choices)
    severity = models.CharField(max_length=10, choices=Severity.choices)
    title = models.CharField(max_length=200)
    detail = models.CharField(max_length=500, blank=True)
    drone_id = models.CharField(max_length=64, blank=True)
    mission_id = models.UUIDField(null=True, blank=True)
    # What made it (an event, a drone going offline at a time): the same happening seen
    # twice (a retried message, two gateways) makes one alert.
    source = models.CharField(max_length=200, unique=True)
    at = models.DateTimeField(default=timezone.now)

    class Meta:
        ordering = ["-at"]
        indexes = [models.Index(fields=["organisation", "-at"])]

    def __str__(self) -> str:
        return f"{self.get_kind_display()}: {self.title}"

    def to_dict(self) -> dict:
        return {
            "id": str(self.id),
            "kind": self.kind,
            "severity": self.severity,
            "title": self.title,
            "detail": self.detail,
            "drone_id": self.drone_id or None,
            "mission_id": str(self.mission_id) if self.mission_id else None,
            "at": self.at.isoformat(),
        }


class Delivery(models.Model):
    class Channel(models.TextChoices):
        EMAIL = "email", "E-mail"
        WEBHOOK = "webhook", "Webhook"

    class Status(models.TextChoices):
        PENDING = "pending", "Pending"
        DELIVERED = "delivered", "Delivered"
        FAILED = "failed", "Failed"

    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    alert = models.ForeignKey(Alert, on_delete=models.CASCADE, related_name="deliveries")
    channel = models.CharField(max_length=10, choices=Channel.choices)
    recipient = models.CharField(max_length=500)
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    attempts = models.PositiveIntegerField(default=0)
    last_error = models.CharField(max_length=500, blank=True)
    delivered_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        constraints = [
            models.UniqueConstraint(
                fields=["alert", "recipient"], name="one_delivery_per_recipient"
            )
        ]

    def __str__(self) -> str:
        return f"{self.alert} → {self.recipient} ({self.status})"

"""Missions, their steps, which drone was given which steps, and everything that happened."""

from __future__ import annotations

import uuid

from django.conf import settings
from django.db import models
from django.utils import timezone

from fleet.models import Drone, Organisation
from fleet.tenancy import reach


class IllegalTransition(Exception):
    pass


class MissionStatus(models.TextChoices):
    DRAFT = "draft", "Draft"
    RUNNING = "running", "Running"
    PAUSED = "paused", "Paused (waiting for a drone)"
    COMPLETED = "completed", "Completed"
    STOPPED = "stopped", "Stopped"
    FAILED = "failed", "Failed"


MISSION_TRANSITIONS: dict[str, set[str]] = {
    MissionStatus.DRAFT: {MissionStatus.RUNNING, MissionStatus.STOPPED},
    MissionStatus.RUNNING: {
        MissionStatus.PAUSED,
        MissionStatus.COMPLETED,
        MissionStatus.STOPPED,
        MissionStatus.FAILED,
    },
    MissionStatus.PAUSED: {MissionStatus.RUNNING, MissionStatus.STOPPED, MissionStatus.FAILED},
    MissionStatus.COMPLETED: set(),
    MissionStatus.STOPPED: set(),
    MissionStatus.FAILED: set(),
}


class StepStatus(models.TextChoices):
    PENDING = "pending", "Pending"
    STARTED = "started", "Started"
    COMPLETED = "completed", "Completed"
    FAILED = "failed", "Failed"
    # Replaced by a collaborative re-plan: no drone will fly it any more.
    SUPERSEDED = "superseded", "Superseded"


STEP_TRANSITIONS: dict[str, set[str]] = {
    StepStatus.PENDING: {
        StepStatus.STARTED,
        StepStatus.COMPLETED,
        StepStatus.FAILED,
        StepStatus.SUPERSEDED,
    },
    StepStatus.STARTED: {
        StepStatus.COMPLETED,
        StepStatus.FAILED,
        StepStatus.PENDING,
        StepStatus.SUPERSEDED,
    },
    StepStatus.FAILED: {
        StepStatus.PENDING,
        StepStatus.STARTED,
        StepStatus.COMPLETED,
        StepStatus.SUPERSEDED,
    },
    StepStatus.COMPLETED: set(),
    StepStatus.SUPERSEDED: set(),
}
# A mission is done when every step is in one of these, whoever did it.
STEP_DONE = {StepStatus.COMPLETED, StepStatus.SUPERSEDED}


class MissionQuerySet(models.QuerySet):
    def for_user(self, user) -> MissionQuerySet:  # type: ignore[no-untyped-def]
        if not user.is_authenticated:
            return self.none()
        return self.filter(reach(user))


class Mission(models.Model):
    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="missions"
    )
    name = models.CharField(max_length=200)
    status = models.CharField(
        max_length=12, choices=MissionStatus.choices, default=MissionStatus.DRAFT
    )
    altitude = models.FloatField(default=10.0)
    # Extensibility parameters: the area and step a collaboration rebuilds.
    extensibility = models.JSONField(null=True, blank=True)
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    created_at = models.DateTimeField(auto_now_add=True)
    started_at = models.DateTimeField(null=True, blank=True)
    ended_at = models.DateTimeField(null=True, blank=True)
    # Paused by an operator: its drones hold where they are until it is resumed.
    held = models.BooleanField(default=False)
    # An imported plan's own geofence (QGroundControl geoFence shape), enforced on top of
    # the organisation's envelope when the mission starts, and its planned home
    # [lat, lon, AMSL altitude].
    fence = models.JSONField(null=True, blank=True)
    plan_home = models.JSONField(null=True, blank=True)

    objects = MissionQuerySet.as_manager()

    class Meta:
        ordering = ["-created_at"]
        indexes = [models.Index(fields=["organisation", "status"])]

    def __str__(self) -> str:
        return self.name

    def transition(self, new: str) -> None:
        """The one place mission states change; refuses illegal moves."""
        if new not in MISSION_TRANSITIONS[MissionStatus(self.status)]:
            raise IllegalTransition(f"mission cannot go from {self.status} to {new}")
        self.status = new
        now = timezone.now()
        if new == MissionStatus.RUNNING and self.started_at is None:
            self.started_at = now
        if new in {MissionStatus.COMPLETED, MissionStatus.STOPPED, MissionStatus.FAILED}:
            self.ended_at = now


class Step(models.Model):
    mission = models.ForeignKey(Mission, on_delete=models.CASCADE, related_name="steps")
    index = models.PositiveIntegerField()
    command = models.CharField(max_length=40)
    params = models.JSONField(default=dict, blank=True)
    status = models.CharField(max_length=10, choices=StepStatus.choices, default=StepStatus.PENDING)
    drone = models.ForeignKey(
        Drone, null=True, blank=True, on_delete=models.SET_NULL, related_name="steps_done"
    )
    started_at = models.DateTimeField(null=True, blank=True)
    ended_at = models.DateTimeField(null=True, blank=True)
    position = models.JSONField(null=True, blank=True)
    duration_s = models.FloatField(null=True, blank=True)
    result = models.JSONField(null=True, blank=True)

    class Meta:
        ordering = ["mission", "index"]
        constraints = [
            models.UniqueConstraint(fields=["mission", "index"], name="one_step_per_index")
        ]

    def __str__(self) -> str:
        return f"{self.mission} #{self.index} {self.command}"

    def transition(self, new: str) -> None:
        if new == self.status:
            return
        if new not in STEP_TRANSITIONS[StepStatus(self.status)]:
            raise IllegalTransition(f"step cannot go from {self.status} to {new}")
        self.status = new


class Assignment(models.Model):
    class Reason(models.TextChoices):
        INITIAL = "initial", "Initial"
        REPLACEMENT = "replacement", "Replacement"
        COLLABORATION = "collaboration", "Collaboration"

    class Status(models.TextChoices):
        # Waiting for the drone to finish its previous assignment of this mission.
        QUEUED = "queued", "Queued"
        SENT = "sent", "Sent"
        ACCEPTED = "accepted", "Accepted"
        REJECTED = "rejected", "Rejected"
        COMPLETED = "completed", "Completed"
        STOPPED = "stopped", "Stopped"

    id = models.UUIDField(primary_key=True, default=uuid.uuid4, editable=False)
    mission = models.ForeignKey(Mission, on_delete=models.CASCADE, related_name="assignments")
    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="assignments")
    step_indexes = models.JSONField(default=list)
    # Steps sent in this assignment that are not part of the mission (preparation).
    preparation = models.JSONField(default=list, blank=True)
    reason = models.CharField(max_length=14, choices=Reason.choices, default=Reason.INITIAL)
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.SENT)
    created_at = models.DateTimeField(auto_now_add=True)
    decode_ms = models.FloatField(null=True, blank=True)
    # The drone holds where it is (its own page's Hold, or the mission's Pause) until resumed.
    held = models.BooleanField(default=False)
    # The failing assignment this one replaces: one replacement per failure, by constraint.
    replaces = models.OneToOneField(
        "self", null=True, blank=True, on_delete=models.SET_NULL, related_name="replaced_by"
    )

    class Meta:
        ordering = ["created_at"]

    ACTIVE = (Status.QUEUED, Status.SENT, Status.ACCEPTED)

    def __str__(self) -> str:
        return f"{self.mission} → {self.drone} ({self.reason})"

    def transition(self, new: str) -> None:
        """The one place assignment states change; refuses illegal moves."""
        if new not in ASSIGNMENT_TRANSITIONS[Assignment.Status(self.status)]:
            raise IllegalTransition(f"assignment cannot go from {self.status} to {new}")
        self.status = new


ASSIGNMENT_TRANSITIONS: dict[str, set[str]] = {
    Assignment.Status.QUEUED: {Assignment.Status.SENT, Assignment.Status.STOPPED},
    # A lost "accepted" must not block "completed" (QoS 1 is at least once, not in order
    # across a gateway restart).
    Assignment.Status.SENT: {
        Assignment.Status.ACCEPTED,
        Assignment.Status.REJECTED,
        Assignment.Status.COMPLETED,
        Assignment.Status.STOPPED,
    },
    Assignment.Status.ACCEPTED: {Assignment.Status.COMPLETED, Assignment.Status.STOPPED},
    Assignment.Status.REJECTED: set(),
    Assignment.Status.COMPLETED: set(),
    Assignment.Status.STOPPED: set(),
}


class Event(models.Model):
    """Every progress message, alarm, handover and decision of a mission."""

    class Kind(models.TextChoices):
        MISSION = "mission", "Mission progress"
        STEP = "step", "Step progress"
        ALARM = "alarm", "Alarm"
        HANDOVER = "handover", "Handover"
        DECISION = "decision", "Decision"
        OPERATOR = "operator", "Operator action"

    mission = models.ForeignKey(Mission, on_delete=models.CASCADE, related_name="events")
    drone = models.ForeignKey(Drone, null=True, blank=True, on_delete=models.SET_NULL)
    kind = models.CharField(max_length=10, choices=Kind.choices)
    at = models.DateTimeField(default=timezone.now)
    message = models.CharField(max_length=300, blank=True)
    data = models.JSONField(default=dict, blank=True)
    # Which drone message recorded it (drone, kind, its own fields and timestamp): a
    # message delivered again, or retried after an outage, is recorded once.
    message_key = models.CharField(max_length=255, blank=True, default="", editable=False)

    class Meta:
        ordering = ["at", "id"]
        indexes = [models.Index(fields=["mission", "at"])]
        constraints = [
            models.UniqueConstraint(
                fields=["mission", "message_key"],
                condition=~models.Q(message_key=""),
                name="missions_event_one_per_message",
            )
        ]

    def __str__(self) -> str:
        return f"{self.mission} {self.kind} {self.message}"


def picture_path(picture: Picture, filename: str) -> str:
    return f"missions/{picture.mission_id}/pictures/{filename}"


class Picture(models.Model):
    """A picture taken by `takepic` in a mission, stored geotagged (EXIF GPS)."""

    mission = models.ForeignKey(Mission, on_delete=models.CASCADE, related_name="pictures")
    drone = models.ForeignKey(Drone, null=True, blank=True, on_delete=models.SET_NULL)
    index = models.PositiveIntegerField(null=True, blank=True)
    name = models.CharField(max_length=255)
    taken_at = models.DateTimeField()
    lat = models.FloatField(null=True, blank=True)
    lon = models.FloatField(null=True, blank=True)
    alt = models.FloatField(null=True, blank=True)
    attitude = models.JSONField(null=True, blank=True)
    image = models.FileField(upload_to=picture_path, max_length=300)
    thumbnail = models.FileField(upload_to=picture_path, max_length=300, blank=True)

    class Meta:
        ordering = ["taken_at", "id"]
        constraints = [
            models.UniqueConstraint(
                fields=["mission", "drone", "name"], name="one_picture_per_name"
            )
        ]

    def __str__(self) -> str:
        return f"{self.mission} {self.name}"

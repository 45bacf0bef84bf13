from __future__ import annotations

from django.conf import settings
from django.db import models

from fleet.models import Drone, Organisation
from missions.models import Mission


def still_path(still: VideoStill, filename: str) -> str:
    return f"video/{still.drone.drone_id}/stills/{filename}"


class VideoStill(models.Model):
    """A frame taken from a drone's live stream on demand, stored like a mission picture:
    geotagged (EXIF GPS), with the drone's attitude and a thumbnail, and attached to the
    mission the drone was flying, if any."""

    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="video_stills")
    mission = models.ForeignKey(
        Mission, null=True, blank=True, on_delete=models.SET_NULL, related_name="video_stills"
    )
    taken_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    # When the frame was captured (the time drawn into it), not when it was asked for.
    taken_at = models.DateTimeField()
    lat = models.FloatField(null=True, blank=True)
    lon = models.FloatField(null=True, blank=True)
    alt = models.FloatField(null=True, blank=True)
    attitude = models.JSONField(null=True, blank=True)
    width = models.PositiveIntegerField()
    height = models.PositiveIntegerField()
    image = models.FileField(upload_to=still_path, max_length=300)
    thumbnail = models.FileField(upload_to=still_path, max_length=300)

    class Meta:
        ordering = ["-taken_at", "-id"]
        indexes = [models.Index(fields=["drone", "-taken_at"])]

    def __str__(self) -> str:
        return f"{self.drone} still {self.taken_at:%Y-%m-%d %H:%M:%S}"


class VideoRecording(models.Model):
    """One stream's video as the media server recorded it (WebM, VP8); the flights it
    belongs to are those of its drone whose time overlaps it."""

    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="video_recordings")
    started_at = models.DateTimeField()
    ended_at = models.DateTimeField()
    file = models.FileField(max_length=300)
    size = models.PositiveBigIntegerField()
    frames = models.PositiveIntegerField()
    width = models.PositiveIntegerField()
    height = models.PositiveIntegerField()
    truncated = models.BooleanField(default=False)

    class Meta:
        ordering = ["started_at", "id"]
        indexes = [models.Index(fields=["drone", "started_at"])]

    def __str__(self) -> str:
        return f"{self.drone} video {self.started_at:%Y-%m-%d %H:%M:%S}"


class VideoRetention(models.Model):
    """How long an organisation keeps its recorded video and how much of it in all; an
    empty field takes the platform's setting (LIVE_VIDEO_RECORDING_KEEP_DAYS,
    LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG)."""

    organisation = models.OneToOneField(
        Organisation, on_delete=models.CASCADE, related_name="video_retention"
    )
    keep_days = models.PositiveIntegerField(null=True, blank=True)
    max_bytes = models.PositiveBigIntegerField(null=True, blank=True)

    def __str__(self) -> str:
        return f"{self.organisation} video retention"

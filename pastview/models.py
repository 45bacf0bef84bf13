"""Per-drone settings of the past-image view, edited on the page and read by the service."""

from __future__ import annotations

import logging
from typing import Any

from django.conf import settings as django_settings
from django.db import models

from pastview.selection import PastViewSettings
from pastview.service import DEFAULT_CAMERA, default_settings

log = logging.getLogger(__name__)


class ViewSettingsQuerySet(models.QuerySet):
    def for_drone_id(self, drone_id: str) -> PastViewSettings | None:
        """The drone's stored settings, or None when it has none (the defaults apply)."""
        row = self.filter(drone__drone_id=drone_id).first()
        return None if row is None else row.past_view_settings()


class ViewSettings(models.Model):
    drone = models.OneToOneField(
        "fleet.Drone", on_delete=models.CASCADE, related_name="pastview_settings"
    )
    # PastViewSettings.to_dict(): evaluation function with its coefficients, buffer, video.
    settings = models.JSONField(default=dict)
    # The camera the frames come from, for drawing: horizontal field of view and mount tilt.
    camera_fov_deg = models.FloatField(default=DEFAULT_CAMERA["fov_deg"])
    camera_pitch_down_deg = models.FloatField(default=DEFAULT_CAMERA["pitch_down_deg"])
    updated_at = models.DateTimeField(auto_now=True, db_index=True)
    updated_by = models.ForeignKey(
        django_settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )

    objects = ViewSettingsQuerySet.as_manager()

    class Meta:
        verbose_name = "past-view settings"
        verbose_name_plural = "past-view settings"

    def __str__(self) -> str:
        return f"past view of {self.drone_id}"

    def past_view_settings(self) -> PastViewSettings:
        """The stored settings, validated; broken ones (an older format) give the defaults."""
        if not self.settings:
            return default_settings()
        try:
            return PastViewSettings.from_dict(self.settings)
        except ValueError as exc:
            log.warning(
                "past-view settings of %s unusable (%s); using defaults", self.drone_id, exc
            )
            return default_settings()

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.past_view_settings().to_dict(),
            "camera": {
                "fov_deg": self.camera_fov_deg,
                "pitch_down_deg": self.camera_pitch_down_deg,
            },
        }

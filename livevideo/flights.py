"""Which recordings belong to a flight: its drone's, overlapping the flight's time."""

from __future__ import annotations

from django.db.models import QuerySet

from records.models import FlightRecord

from .models import VideoRecording


def recordings_of(flight: FlightRecord) -> QuerySet[VideoRecording]:
    if flight.drone_id is None:
        return VideoRecording.objects.none()
    return VideoRecording.objects.filter(
        drone_id=flight.drone_id,
        started_at__lt=flight.ended_at,
        ended_at__gt=flight.started_at,
    ).select_related("drone")


def file_url(row: VideoRecording) -> str:
    return f"/api/v1/drones/{row.drone.drone_id}/video/recordings/{row.pk}/file/"

"""Which recordings a mission's log viewer plays: those of the mission's flights.

A flight record tied to the mission (records.FlightRecord.mission) owns its drone's
recordings overlapping its time (livevideo.flights); the mission's are the union over its
flights, each once, in the order they start.
"""

from __future__ import annotations

from django.db.models import Q, QuerySet

from missions.models import Mission
from records.models import FlightRecord

from .models import VideoRecording

# A mission's flights looked at, newest first: bounds the query's size for a mission that
# ran for very long with many replacements.
MAX_FLIGHTS = 500


def recordings_of_mission(mission: Mission) -> QuerySet[VideoRecording]:
    flights = (
        FlightRecord.objects.filter(mission=mission, drone__isnull=False)
        .order_by("-started_at")
        .values_list("drone_id", "started_at", "ended_at")[:MAX_FLIGHTS]
    )
    if not flights:
        return VideoRecording.objects.none()
    overlapping = Q()
    for drone_id, started_at, ended_at in flights:
        overlapping |= Q(drone_id=drone_id, started_at__lt=ended_at, ended_at__gt=started_at)
    return (
        VideoRecording.objects.filter(overlapping)
        .select_related("drone")
        .order_by("started_at", "pk")
    )

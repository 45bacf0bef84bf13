"""`{% flight_video record %}`: the flight's recorded video on its record page."""

from __future__ import annotations

from django import template

from records.models import FlightRecord

from ..flights import file_url, recordings_of

register = template.Library()


@register.inclusion_tag("livevideo/_flight_video.html")
def flight_video(record: FlightRecord) -> dict:
    rows = list(recordings_of(record))
    return {
        "recordings": [
            {
                "row": row,
                "url": file_url(row),
                "offset_s": (row.started_at - record.started_at).total_seconds(),
            }
            for row in rows
        ]
    }

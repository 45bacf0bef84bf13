"""Which recordings a flight log's viewer plays in step with its plots.

A log whose samples are stamped with Unix time (a ground station's .tlog, the platform's
recorders) shares its clock with the video's capture times (onboard/framecode.py), so the
recordings of the log's drone that overlap the log's span play on its time axis. A log on
a board's boot clock has no such tie and shows no video.
"""

from __future__ import annotations

from datetime import UTC, datetime

from django.db.models import QuerySet

from logs.models import FlightLog

from .models import VideoRecording

# The viewer's own rule for a wall-clock log (static/js/logs/viewer.js): stamps after
# 2000-01-01 are Unix seconds, not seconds since a board's power-up.
UNIX_CLOCK_FROM_S = 946_684_800


def on_unix_clock(log: FlightLog) -> bool:
    return log.start_s is not None and log.end_s is not None and log.start_s > UNIX_CLOCK_FROM_S


def recordings_of_log(log: FlightLog) -> QuerySet[VideoRecording]:
    if log.drone_id is None or not on_unix_clock(log):
        return VideoRecording.objects.none()
    start = datetime.fromtimestamp(log.start_s, UTC)
    end = datetime.fromtimestamp(log.end_s, UTC)
    return VideoRecording.objects.filter(
        drone_id=log.drone_id, started_at__lt=end, ended_at__gt=start
    ).select_related("drone")

"""Who may publish and watch, as the ground's settings and database say.

Publishing: a drone's broker credentials (its id and password, checked against the hash
kept on the Drone, fleet.credentials), not revoked. Watching: a ticket the portal signs
with the key here for a member of the drone's organisation (livevideo.tickets).
"""

from __future__ import annotations

import asyncio
import hashlib
from datetime import UTC, datetime
from pathlib import Path

from django.conf import settings
from django.db import close_old_connections

from fleet.models import Drone
from workers.broker.credentials import check_password

from .models import VideoRecording
from .recording import Recorded, Recorder
from .relay import Limits


def ticket_key() -> bytes:
    """LIVE_VIDEO_TICKET_KEY, or a key derived from SECRET_KEY for this one purpose."""
    if settings.LIVE_VIDEO_TICKET_KEY:
        return settings.LIVE_VIDEO_TICKET_KEY.encode()
    return hashlib.sha256(
        b"skyhive-live-video-ticket-key\0" + settings.SECRET_KEY.encode()
    ).digest()


def limits() -> Limits:
    return Limits(
        max_streams=settings.LIVE_VIDEO_MAX_STREAMS,
        max_viewers=settings.LIVE_VIDEO_MAX_VIEWERS,
        max_viewers_per_stream=settings.LIVE_VIDEO_MAX_VIEWERS_PER_STREAM,
        max_bitrate_bps=settings.LIVE_VIDEO_MAX_BITRATE_BPS,
        max_width=settings.LIVE_VIDEO_MAX_WIDTH,
        max_height=settings.LIVE_VIDEO_MAX_HEIGHT,
    )


def drone_organisation(drone_id: str, password: str) -> int | None:
    """The organisation of the drone these credentials belong to, or None."""
    close_old_connections()
    row = (
        Drone.objects.filter(drone_id=drone_id, credentials_revoked=False)
        .exclude(mqtt_password_hash="")
        .values_list("organisation_id", "mqtt_password_hash")
        .first()
    )
    if row is None or not check_password(password, row[1]):
        return None
    return row[0]


async def authenticate(drone_id: str, password: str) -> int | None:
    return await asyncio.to_thread(drone_organisation, drone_id, password)


def recording_path(drone_id: str, started: datetime) -> Path:
    """Where a recording of `drone_id` starting at `started` is written (under MEDIA_ROOT)."""
    name = f"{started:%Y%m%dT%H%M%S%f}.webm"
    return Path(settings.MEDIA_ROOT) / "video" / drone_id / "recordings" / name


def start_recording(drone_id: str) -> Recorder:
    return Recorder(
        recording_path(drone_id, datetime.now(UTC)), settings.LIVE_VIDEO_RECORDING_MAX_BYTES
    )


def file_recording(drone_id: str, organisation_id: int, recorded: Recorded) -> bool:
    """Keep the finished recording with the drone that published it (flights find it by
    time). A drone removed meanwhile, or its id now another organisation's, keeps nothing:
    the file is deleted and False returned."""
    close_old_connections()
    drone = Drone.objects.filter(drone_id=drone_id, organisation_id=organisation_id).first()
    if drone is None:
        recorded.path.unlink(missing_ok=True)
        return False
    VideoRecording.objects.create(
        drone=drone,
        started_at=recorded.started_at,
        ended_at=recorded.ended_at,
        file=str(recorded.path.relative_to(settings.MEDIA_ROOT)),
        size=recorded.size,
        frames=recorded.frames,
        width=recorded.width,
        height=recorded.height,
        truncated=recorded.truncated,
    )
    return True


async def recorded(drone_id: str, organisation_id: int, done: Recorded) -> bool:
    return await asyncio.to_thread(file_recording, drone_id, organisation_id, done)

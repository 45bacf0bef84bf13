"""Stills from the live stream: the media server's newest frame, kept like a mission
picture (missions/pictures.py): geotagged with the drone's position, its attitude, a
thumbnail, and the mission it was flying."""

from __future__ import annotations

import io
from datetime import UTC, datetime

from django.core.files.base import ContentFile
from PIL import ImageOps

from fleet.models import Drone
from missions.pictures import THUMBNAIL_SIZE, exif_gps, with_exif
from missions.progress import find_mission
from telemetry import queries
from workers.images import open_image

from . import client
from .models import VideoStill

ATTITUDE_OBJECT = "AttitudeActual"  # both flight-controller drivers report it (degrees)


class NotLive(Exception):
    """The drone has no live stream to take a still from."""


def attitude_of(drone: Drone) -> dict | None:
    sample = queries.latest(drone.pk, [ATTITUDE_OBJECT]).get(ATTITUDE_OBJECT)
    if sample is None:
        return None
    fields = sample["fields"]
    if not all(name in fields for name in ("Roll", "Pitch", "Yaw")):
        return None
    return {"roll": fields["Roll"], "pitch": fields["Pitch"], "yaw": fields["Yaw"]}


def _thumbnail(jpeg: bytes) -> tuple[bytes, int, int]:
    with open_image(jpeg) as image:
        size = image.size
        image = ImageOps.exif_transpose(image.convert("RGB"))
        image.thumbnail(THUMBNAIL_SIZE)
        buffer = io.BytesIO()
        image.save(buffer, "JPEG", quality=80)
    return buffer.getvalue(), size[0], size[1]


def take(drone: Drone, user) -> VideoStill:  # type: ignore[no-untyped-def]
    """Store the stream's newest frame now; NotLive when there is none."""
    frame = client.still(drone.drone_id)
    if frame is None:
        raise NotLive(drone.drone_id)
    jpeg, captured_ms = frame
    taken_at = (
        datetime.fromtimestamp(captured_ms / 1000, tz=UTC) if captured_ms else datetime.now(UTC)
    )
    if drone.lat is not None and drone.lon is not None:
        jpeg = with_exif(jpeg, exif_gps(drone.lat, drone.lon, drone.alt, taken_at))
    thumbnail, width, height = _thumbnail(jpeg)
    mission_id = (drone.mission or {}).get("mission_id")
    still = VideoStill(
        drone=drone,
        mission=find_mission(drone, mission_id) if mission_id else None,
        taken_by=user if getattr(user, "is_authenticated", False) else None,
        taken_at=taken_at,
        lat=drone.lat,
        lon=drone.lon,
        alt=drone.alt,
        attitude=attitude_of(drone),
        width=width,
        height=height,
    )
    stamp = taken_at.strftime("%Y%m%dT%H%M%S%f")
    still.image.save(f"{drone.drone_id}_{stamp}.jpg", ContentFile(jpeg), save=False)
    still.thumbnail.save(f"thumb_{drone.drone_id}_{stamp}.jpg", ContentFile(thumbnail), save=False)
    still.save()
    return still


def describe(still: VideoStill) -> dict:
    base = f"/api/v1/drones/{still.drone.drone_id}/video/stills/{still.pk}/"
    return {
        "id": still.pk,
        "drone": still.drone.drone_id,
        "mission": str(still.mission_id) if still.mission_id else None,
        "taken_at": still.taken_at.isoformat(),
        "position": None
        if still.lat is None
        else {"lat": still.lat, "lon": still.lon, "alt": still.alt},
        "attitude": still.attitude,
        "width": still.width,
        "height": still.height,
        "image": base + "image/",
        "thumbnail": base + "thumbnail/",
    }

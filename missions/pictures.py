"""Mission pictures: stored geotagged, thumbnailed, zipped for OpenDroneMap.

The gateway stores them on lanes of their own (workers.gateway), so decoding a large
picture holds up no other drone's messages; an image declaring more than
workers.images.MAX_PIXELS is refused (`too_many_pixels`) before it is decoded.

Geotagging writes an EXIF GPS block into the JPEG without re-encoding it (the APP1
segment is replaced), so pictures keep their quality. The optional barrel-distortion
correction is ImageMagick's `-distort barrel 'A B C D'` ([Paula 2018], listing 5.1) done
with numpy: a destination pixel at normalised radius r samples the source at
r · (A r³ + B r² + C r + D), radius 1 being half the smaller image side.
"""

from __future__ import annotations

import io
import logging
import struct
import zipfile
from collections.abc import Iterable
from datetime import UTC, datetime
from pathlib import PurePath

import numpy as np
from django.core.files.base import ContentFile
from django.db import IntegrityError, transaction
from django.urls import reverse
from PIL import Image, ImageOps

from fleet.models import Drone
from missions import live
from missions.models import Mission, Picture
from missions.progress import find_mission
from onboard import protocol
from workers.images import ImageRefused, open_image

log = logging.getLogger(__name__)

# The GoPro Hero3 correction of [Paula 2018], listing 5.1:
# `convert -distort barrel '0.1 -0.32 0'`, D = 1.22.
BARREL_COEFFICIENTS = (0.10, -0.32, 0.0, 1.22)
THUMBNAIL_SIZE = (240, 240)
GPS_IFD = 0x8825
EXIF_MARKER = b"Exif\x00\x00"


# ---------------------------------------------------------------------------------------
# EXIF GPS.


def _dms(value: float) -> tuple[float, float, float]:
    value = abs(value)
    degrees = int(value)
    minutes_full = (value - degrees) * 60
    minutes = int(minutes_full)
    return float(degrees), float(minutes), round((minutes_full - minutes) * 60, 4)


def exif_gps(lat: float, lon: float, alt: float | None, taken_at: datetime) -> bytes:
    """An APP1 payload (starting with `Exif\\0\\0`) holding the position and time."""
    exif = Image.Exif()
    exif[0x0132] = taken_at.strftime("%Y:%m:%d %H:%M:%S")  # DateTime
    gps = {
        0: b"\x02\x03\x00\x00",  # GPSVersionID 2.3
        1: "N" if lat >= 0 else "S",
        2: _dms(lat),
        3: "E" if lon >= 0 else "W",
        4: _dms(lon),
        7: (float(taken_at.hour), float(taken_at.minute), float(taken_at.second)),
        29: taken_at.strftime("%Y:%m:%d"),
    }
    if alt is not None:
        gps[5] = b"\x00" if alt >= 0 else b"\x01"
        gps[6] = abs(float(alt))
    exif[GPS_IFD] = gps
    return exif.tobytes()


def _segments(jpeg: bytes) -> Iterable[tuple[int, int, int]]:
    """(marker, start, end) of each header segment before the scan data."""
    pos = 2
    while pos + 4 <= len(jpeg) and jpeg[pos] == 0xFF:
        marker = jpeg[pos + 1]
        if marker == 0xDA:  # start of scan: the rest is image data
            return
        (length,) = struct.unpack(">H", jpeg[pos + 2 : pos + 4])
        yield marker, pos, pos + 2 + length
        pos += 2 + length


def with_exif(jpeg: bytes, exif_payload: bytes) -> bytes:
    """The JPEG with its EXIF APP1 segment replaced (or added after SOI/JFIF)."""
    if not jpeg.startswith(b"\xff\xd8"):
        raise ValueError("not a JPEG")
    if len(exif_payload) + 2 > 0xFFFF:
        raise ValueError("EXIF block too large")
    kept = bytearray(b"\xff\xd8")
    insert_at = None
    end = 2
    for marker, start, stop in _segments(jpeg):
        end = stop
        if marker == 0xE1 and jpeg[start + 4 : start + 10] == EXIF_MARKER:
            continue
        kept += jpeg[start:stop]
        if marker == 0xE0:
            insert_at = len(kept)
    segment = b"\xff\xe1" + struct.pack(">H", len(exif_payload) + 2) + exif_payload
    position = insert_at if insert_at is not None else 2
    kept[position:position] = segment
    return bytes(kept) + jpeg[end:]


def read_gps(jpeg: bytes) -> tuple[float, float, float | None] | None:
    """(lat, lon, alt) from a JPEG's EXIF GPS block, or None."""
    with Image.open(io.BytesIO(jpeg)) as image:
        gps = image.getexif().get_ifd(GPS_IFD)
    if not gps or 2 not in gps or 4 not in gps:
        return None

    def degrees(dms: tuple, ref: str, negative: str) -> float:
        value = float(dms[0]) + float(dms[1]) / 60 + float(dms[2]) / 3600
        return -value if ref == negative else value

    lat = degrees(gps[2], gps.get(1, "N"), "S")
    lon = degrees(gps[4], gps.get(3, "E"), "W")
    alt = None
    if 6 in gps:
        alt = float(gps[6]) * (-1 if gps.get(5) == b"\x01" else 1)
    return lat, lon, alt


# ---------------------------------------------------------------------------------------
# Barrel distortion.


def undistort(
    jpeg: bytes, coefficients: tuple[float, float, float, float] = BARREL_COEFFICIENTS
) -> bytes:
    """ImageMagick's barrel distortion with the given A, B, C, D, bilinear sampling."""
    a, b, c, d = coefficients
    with Image.open(io.BytesIO(jpeg)) as image:
        exif = image.info.get("exif")
        source = np.asarray(image.convert("RGB"), dtype=np.float32)
    height, width = source.shape[:2]
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    norm = min(width, height) / 2.0
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    dx, dy = (xs - cx) / norm, (ys - cy) / norm
    r = np.sqrt(dx * dx + dy * dy)
    scale = a * r**3 + b * r**2 + c * r + d
    sx = cx + dx * scale * norm
    sy = cy + dy * scale * norm
    x0 = np.floor(sx).astype(np.int64)
    y0 = np.floor(sy).astype(np.int64)
    fx, fy = (sx - x0)[..., None], (sy - y0)[..., None]
    inside = (x0 >= 0) & (y0 >= 0) & (x0 < width - 1) & (y0 < height - 1)
    x0c, y0c = np.clip(x0, 0, width - 2), np.clip(y0, 0, height - 2)
    top = source[y0c, x0c] * (1 - fx) + source[y0c, x0c + 1] * fx
    bottom = source[y0c + 1, x0c] * (1 - fx) + source[y0c + 1, x0c + 1] * fx
    out = (top * (1 - fy) + bottom * fy) * inside[..., None]
    result = Image.fromarray(np.clip(out + 0.5, 0, 255).astype(np.uint8), "RGB")
    buffer = io.BytesIO()
    result.save(buffer, "JPEG", quality=92, **({"exif": exif} if exif else {}))
    return buffer.getvalue()


# ---------------------------------------------------------------------------------------
# Storing and exporting.


def _thumbnail(jpeg: bytes) -> bytes:
    # Refuses a decompression bomb (workers.images) before decoding a pixel.
    with open_image(jpeg) as image:
        image = ImageOps.exif_transpose(image.convert("RGB"))
        image.thumbnail(THUMBNAIL_SIZE)
        buffer = io.BytesIO()
        image.save(buffer, "JPEG", quality=80)
    return buffer.getvalue()


def safe_name(name: str) -> str:
    base = PurePath(name.replace("\\", "/")).name
    cleaned = "".join(ch if ch.isalnum() or ch in "._-" else "_" for ch in base).strip("._")
    return (cleaned or "picture")[:200]


def store_picture(drone: Drone, picture: protocol.Picture) -> str | None:
    """Keep a `<id>/pictures/out` picture with its mission and step, geotagged."""
    if picture.mission_id is None:
        return "picture_outside_mission"
    mission = find_mission(drone, picture.mission_id)
    if mission is None:
        return "unknown_mission"
    taken_at = datetime.fromtimestamp(picture.ts, tz=UTC)
    position = picture.position
    jpeg = picture.jpeg
    try:
        if position is not None:
            jpeg = with_exif(jpeg, exif_gps(position.lat, position.lon, position.alt, taken_at))
        thumbnail = _thumbnail(jpeg)
    except ImageRefused as exc:
        log.warning("picture from %s refused: %s", drone.drone_id, exc)
        return exc.reason
    except (OSError, ValueError, struct.error, SyntaxError):
        return "unreadable_picture"
    name = safe_name(picture.name)
    try:
        with transaction.atomic():
            row = Picture(
                mission=mission,
                drone=drone,
                index=picture.index,
                name=name,
                taken_at=taken_at,
                lat=None if position is None else position.lat,
                lon=None if position is None else position.lon,
                alt=None if position is None else position.alt,
                attitude=picture.attitude,
            )
            row.image.save(f"{drone.drone_id}_{name}", ContentFile(jpeg), save=False)
            row.thumbnail.save(f"thumb_{drone.drone_id}_{name}", ContentFile(thumbnail), save=False)
            row.save()
    except IntegrityError:
        return "duplicate_picture"
    live.push(
        mission.pk,
        {
            "type": "picture",
            "id": row.pk,
            "name": name,
            "drone": drone.drone_id,
            "index": picture.index,
            "lat": row.lat,
            "lon": row.lon,
            "thumbnail": reverse("missions:picture-thumbnail", args=[row.pk]),
        },
    )
    return None


def odm_archive(mission: Mission, *, correct_barrel: bool = False) -> bytes:
    """A ZIP for OpenDroneMap: the images and `geo.txt` (EPSG:4326, lon lat alt)."""
    buffer = io.BytesIO()
    lines = ["EPSG:4326"]
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for picture in mission.pictures.select_related("drone"):
            with picture.image.open("rb") as handle:
                jpeg = handle.read()
            if correct_barrel:
                jpeg = undistort(jpeg)
            name = PurePath(picture.image.name).name
            archive.writestr(f"images/{name}", jpeg)
            if picture.lat is not None and picture.lon is not None:
                lines.append(f"{name} {picture.lon:.8f} {picture.lat:.8f} {picture.alt or 0.0:.3f}")
        archive.writestr("geo.txt", "\n".join(lines) + "\n")
    return buffer.getvalue()

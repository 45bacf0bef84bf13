"""Pictures: geotagged without re-encoding, thumbnailed, barrel-corrected in Python."""

from __future__ import annotations

import io
import time

import numpy as np
from PIL import Image

from missions import pictures
from missions.models import Mission, Picture
from onboard import protocol

from .conftest import online_drone, point_at


def sample_jpeg(size: tuple[int, int] = (320, 240)) -> bytes:
    """A test chart: a grid of dark lines on white, so distortion moves visible edges."""
    image = np.full((size[1], size[0], 3), 255, dtype=np.uint8)
    image[::20, :, :] = 0
    image[:, ::20, :] = 0
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, "JPEG", quality=95)
    return buffer.getvalue()


def store_sample_picture(drone, mission: Mission, index: int) -> str | None:  # type: ignore[no-untyped-def]
    lat, lon = point_at(8.0 * index, 0)
    message = protocol.Picture(
        name=f"IMG_{index:04d}.JPG",
        position=protocol.Position(lat, lon, 10.0),
        attitude={"roll": 0.0, "pitch": 0.0, "yaw": 90.0},
        mission_id=str(mission.pk),
        index=index,
        jpeg=sample_jpeg(),
        ts=time.time(),
    )
    return pictures.store_picture(drone, message)


def test_geotagging_writes_the_position_into_exif_and_keeps_the_image_data():
    jpeg = sample_jpeg()
    lat, lon = point_at(12, -7)
    from datetime import UTC, datetime

    tagged = pictures.with_exif(jpeg, pictures.exif_gps(lat, lon, 10.5, datetime.now(UTC)))
    read_lat, read_lon, read_alt = pictures.read_gps(tagged)
    assert abs(read_lat - lat) < 1e-6 and abs(read_lon - lon) < 1e-6 and read_alt == 10.5
    # Same scan data: the pixels are identical, nothing was re-encoded.
    assert np.array_equal(
        np.asarray(Image.open(io.BytesIO(tagged))), np.asarray(Image.open(io.BytesIO(jpeg)))
    )
    # Tagging twice replaces the block instead of stacking another one.
    again = pictures.with_exif(tagged, pictures.exif_gps(0.5, 0.5, None, datetime.now(UTC)))
    assert again.count(b"Exif\x00\x00") == 1 and pictures.read_gps(again)[:2] == (0.5, 0.5)


def test_a_picture_from_a_mission_is_stored_with_its_step_geotagged(world):
    drone = online_drone(world.org, "ACME_CAM")
    mission = Mission.objects.create(organisation=world.org, name="photos")
    assert store_sample_picture(drone, mission, 7) is None
    picture = Picture.objects.get(mission=mission)
    assert picture.index == 7 and picture.drone == drone and picture.name == "IMG_0007.JPG"
    with picture.image.open("rb") as handle:
        lat, lon, alt = pictures.read_gps(handle.read())
    assert abs(lat - picture.lat) < 1e-6 and alt == 10.0
    with picture.thumbnail.open("rb") as handle:
        assert max(Image.open(handle).size) <= 240
    assert store_sample_picture(drone, mission, 7) == "duplicate_picture"


def test_a_picture_for_an_unknown_mission_or_a_broken_jpeg_is_dropped(world):
    drone = online_drone(world.org, "ACME_CAM")
    message = protocol.Picture(
        "a.jpg", None, None, "5f1d7a2e-0000-4000-8000-000000000000", 1, sample_jpeg()
    )
    assert pictures.store_picture(drone, message) == "unknown_mission"
    mission = Mission.objects.create(organisation=world.org, name="photos")
    broken = protocol.Picture(
        "b.jpg",
        protocol.Position(40.0, -8.0, 1.0),
        None,
        str(mission.pk),
        1,
        b"\xff\xd8\xff\xe1\x00",
    )
    assert pictures.store_picture(drone, broken) == "unreadable_picture"
    assert not Picture.objects.exists()


def test_barrel_correction_keeps_the_centre_and_moves_the_edges():
    jpeg = sample_jpeg()
    corrected = pictures.undistort(jpeg)
    before = np.asarray(Image.open(io.BytesIO(jpeg)).convert("L"), dtype=float)
    after = np.asarray(Image.open(io.BytesIO(corrected)).convert("L"), dtype=float)
    assert after.shape == before.shape
    cy, cx = before.shape[0] // 2, before.shape[1] // 2
    # D = 1.22 dominates at the centre: a small zoom there, so the centre stays similar...
    assert (
        abs(
            after[cy - 5 : cy + 5, cx - 5 : cx + 5].mean()
            - before[cy - 5 : cy + 5, cx - 5 : cx + 5].mean()
        )
        < 80
    )
    # ...while the grid lines move: the images differ clearly overall.
    assert np.abs(after - before).mean() > 10


def test_barrel_correction_with_identity_coefficients_changes_nothing_but_compression():
    jpeg = sample_jpeg()
    same = pictures.undistort(jpeg, (0.0, 0.0, 0.0, 1.0))
    before = np.asarray(Image.open(io.BytesIO(jpeg)).convert("L"), dtype=float)
    after = np.asarray(Image.open(io.BytesIO(same)).convert("L"), dtype=float)
    inner = (slice(2, -2), slice(2, -2))
    assert np.abs(after[inner] - before[inner]).mean() < 6

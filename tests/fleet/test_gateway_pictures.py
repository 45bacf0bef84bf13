"""Drone pictures at the gateway: decompression bombs refused before decoding, with a
reason counted against the drone, and picture decoding on lanes of its own, so a drone
sending large pictures holds up no other drone's heartbeats."""

from __future__ import annotations

import base64
import io
import json
import struct
import time
import zlib

import numpy as np
import pytest
from PIL import Image

from fleet.models import Drone
from missions.creation import create_mission
from missions.models import Picture
from missions.startstop import start_mission
from runtime.processes import wait_for
from workers import outbox
from workers.counters import REFUSAL_DRONES_KEY, REFUSALS_KEY, refusals
from workers.images import MAX_PIXELS, ImageRefused, open_image

from ..missions.conftest import online_drone
from .conftest import heartbeat, mqtt_client

pytestmark = pytest.mark.e2e

BOMB_SIDE = 10_000  # 100 megapixels: over our limit, under Pillow's own error threshold


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


def png_bomb(side: int = BOMB_SIDE) -> bytes:
    """A real PNG of side x side black 8-bit pixels: ~100 kB that decode to 100 MB."""
    packer = zlib.compressobj(9)
    row = b"\x00" * (side + 1)  # filter byte + pixels
    idat = b"".join(packer.compress(row) for _ in range(side)) + packer.flush()
    header = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)  # 8-bit greyscale
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", idat)
        + _png_chunk(b"IEND", b"")
    )


def small_jpeg(size: tuple[int, int] = (64, 48), noise: bool = False) -> bytes:
    rng = np.random.default_rng(7)
    shape = (size[1], size[0], 3)
    pixels = rng.integers(0, 255, shape, dtype=np.uint8) if noise else np.full(shape, 128, np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, "JPEG", quality=90)
    return buffer.getvalue()


def jpeg_bomb(side: int = BOMB_SIDE) -> bytes:
    """A real JPEG whose frame header declares side x side pixels (decoding it would
    allocate 300 MB)."""
    jpeg = bytearray(small_jpeg())
    sof = jpeg.index(b"\xff\xc0")
    jpeg[sof + 5 : sof + 9] = struct.pack(">HH", side, side)
    return bytes(jpeg)


def test_the_pixel_limit_refuses_bombs_that_pillow_alone_would_decode():
    bomb = png_bomb()
    assert len(bomb) < 200_000
    # Pillow by itself opens it (100 MP is under its error threshold): the limit is ours.
    with Image.open(io.BytesIO(bomb)) as image:
        assert image.size == (BOMB_SIDE, BOMB_SIDE)
    assert BOMB_SIDE * BOMB_SIDE > MAX_PIXELS
    for data, formats in ((bomb, ("PNG",)), (jpeg_bomb(), ("JPEG",))):
        with pytest.raises(ImageRefused) as refused:
            with open_image(data, formats):
                pass
        assert refused.value.reason == "too_many_pixels"
    # Only the formats asked for: a PNG is no drone picture.
    with pytest.raises(ImageRefused) as refused:
        with open_image(bomb):
            pass
    assert refused.value.reason == "unreadable_picture"
    with open_image(small_jpeg()) as image:
        assert image.size == (64, 48)


def _picture(mission_id: str, jpeg: bytes, index: int, name: str) -> str:
    return json.dumps(
        {
            "ts": time.time(),
            "name": name,
            "position": {"lat": 40.63, "lon": -8.65, "alt": 10.0},
            "mission_id": mission_id,
            "index": index,
            "jpeg": base64.b64encode(jpeg).decode("ascii"),
        }
    )


def _refusals_of(drone_id: str) -> dict[str, int]:
    rows = [row for row in refusals() if row["drone_id"] == drone_id]
    return rows[0]["reasons"] if rows else {}


def test_a_decompression_bomb_is_refused_and_counted_against_its_drone(world_tx, broker, gateway):
    outbox.sync_redis().delete(REFUSALS_KEY, REFUSAL_DRONES_KEY)
    drone = online_drone(world_tx.org, "ACME_CAM")
    mission = create_mission(organisation=world_tx.org, name="survey", steps=[{"command": "arm"}])
    start_mission(mission, drone=drone)
    ground = mqtt_client(broker.url_for("ground"))
    topic = "ACME_CAM/pictures/out"
    try:
        for index, (jpeg, name) in enumerate(
            [(jpeg_bomb(), "BOMB.JPG"), (png_bomb(), "BOMB.PNG"), (small_jpeg(), "OK.JPG")]
        ):
            ground.publish(topic, _picture(str(mission.pk), jpeg, index, name), qos=1)
        assert wait_for(lambda: Picture.objects.filter(mission=mission).exists(), 20)
        assert wait_for(lambda: gateway.counters.get("dropped") >= 2 or None, 10)
        gateway.counters.flush()
        reasons = _refusals_of("ACME_CAM")
        assert reasons.get("pictures.too_many_pixels") == 1, reasons
        # The PNG is refused by the contract (a picture is a JPEG) before any decoder.
        assert reasons.get("pictures.malformed") == 1, reasons
        assert list(Picture.objects.filter(mission=mission).values_list("name", flat=True)) == [
            "OK.JPG"
        ]
        assert gateway.client.is_connected()
    finally:
        ground.loop_stop()


def test_large_pictures_from_one_drone_do_not_hold_up_another_drones_heartbeats(
    world_tx, broker, gateway
):
    drone = online_drone(world_tx.org, "ACME_CAM")
    mission = create_mission(organisation=world_tx.org, name="survey", steps=[{"command": "arm"}])
    start_mission(mission, drone=drone)
    Drone.objects.filter(drone_id="ACME_1").update(online=False, battery_remaining=None)
    ground = mqtt_client(broker.url_for("ground"))
    big = small_jpeg((4000, 3000), noise=True)  # 12 MP of noise: slow to decode
    try:
        for index in range(6):
            payload = _picture(str(mission.pk), big, index, f"IMG_{index}.JPG")
            ground.publish("ACME_CAM/pictures/out", payload, qos=1).wait_for_publish(10)
        sent_at = time.monotonic()
        ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
        assert wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).exists(), 10)
        heartbeat_s = time.monotonic() - sent_at
        stored = Picture.objects.filter(mission=mission).count()
        assert stored < 6, "the heartbeat waited for every picture"
        assert wait_for(lambda: Picture.objects.filter(mission=mission).count() == 6, 60)
        pictures_s = time.monotonic() - sent_at
        assert heartbeat_s < pictures_s / 2, (heartbeat_s, pictures_s)
    finally:
        ground.loop_stop()

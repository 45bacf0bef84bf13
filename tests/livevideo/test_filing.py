"""A finished recording is filed with the drone that published it, and only that drone:
a drone removed meanwhile, or an id now another organisation's, keeps nothing."""

from __future__ import annotations

import asyncio
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from livevideo import access
from livevideo.models import VideoRecording
from livevideo.recording import Recorded
from livevideo.relay import Relay, Stream

# Filing runs in the media server's thread, outside any request: committed rows here.
pytestmark = pytest.mark.django_db(transaction=True)


def finished(drone_id: str, media_root: Path) -> Recorded:
    path = access.recording_path(drone_id, datetime.now(UTC))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"webm")
    begun = datetime.now(UTC)
    return Recorded(path, begun, begun + timedelta(seconds=4), 40, 0, 4, 320, 240, False)


@pytest.fixture
def media_root(settings, tmp_path: Path) -> Path:  # type: ignore[no-untyped-def]
    settings.MEDIA_ROOT = str(tmp_path)
    return tmp_path


def test_a_recording_is_filed_with_its_publishers_drone(world_tx, media_root):  # type: ignore[no-untyped-def]
    done = finished(world_tx.drone.drone_id, media_root)
    assert access.file_recording(world_tx.drone.drone_id, world_tx.org.pk, done)
    row = VideoRecording.objects.get()
    assert row.drone == world_tx.drone and row.frames == 40 and done.path.exists()


def test_a_recording_whose_drone_now_belongs_elsewhere_is_deleted(world_tx, media_root):  # type: ignore[no-untyped-def]
    done = finished(world_tx.drone.drone_id, media_root)
    # Published by this id under the other organisation: the drone of that name is not it.
    assert not access.file_recording(world_tx.drone.drone_id, world_tx.other_org.pk, done)
    assert not VideoRecording.objects.exists() and not done.path.exists()
    gone = finished("REMOVED_1", media_root)
    assert not access.file_recording("REMOVED_1", world_tx.org.pk, gone)
    assert not gone.path.exists()


def test_the_relay_counts_a_recording_its_drone_did_not_keep(media_root):  # type: ignore[no-untyped-def]
    filed: list[tuple[str, int]] = []

    async def drone_gone(drone_id: str, organisation_id: int, done: Recorded) -> bool:
        filed.append((drone_id, organisation_id))
        return False

    relay = Relay(on_recorded=drone_gone)
    stream = Stream("ACME_1", 7, "session", pc=None)
    asyncio.run(relay._file(stream, finished("ACME_1", media_root)))
    assert filed == [("ACME_1", 7)]
    assert relay.counts["recordings_drone_gone"] == 1 and relay.counts["recordings"] == 1
    assert relay.health()["recordings_finishing"] == 0

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


def finished(drone_id: str) -> Recorded:
    """A closed recording of `drone_id`, its file under MEDIA_ROOT."""
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
    done = finished(world_tx.drone.drone_id)
    assert access.file_recording(world_tx.drone.drone_id, world_tx.org.pk, done)
    row = VideoRecording.objects.get()
    assert row.drone == world_tx.drone and row.frames == 40 and done.path.exists()


def test_a_recording_whose_drone_now_belongs_elsewhere_is_deleted(world_tx, media_root):  # type: ignore[no-untyped-def]
    done = finished(world_tx.drone.drone_id)
    # Published by this id under the other organisation: the drone of that name is not it.
    assert not access.file_recording(world_tx.drone.drone_id, world_tx.other_org.pk, done)
    assert not VideoRecording.objects.exists() and not done.path.exists()
    gone = finished("REMOVED_1")
    assert not access.file_recording("REMOVED_1", world_tx.org.pk, gone)
    assert not gone.path.exists()


def test_an_ended_stream_counts_as_ending_until_its_recording_is_filed(media_root):  # type: ignore[no-untyped-def]
    import av
    import numpy as np
    from aiortc import RTCPeerConnection

    from livevideo.recording import Recorder

    seen: list[tuple[str, int, int, dict]] = []

    async def drone_gone(drone_id: str, organisation_id: int, done: Recorded) -> bool:
        seen.append((drone_id, organisation_id, done.frames, relay.health()))
        return False

    async def publish_and_end() -> None:
        stream = Stream("ACME_1", 7, "session", RTCPeerConnection())
        relay.streams["ACME_1"] = stream
        stream.recorder = Recorder(access.recording_path("ACME_1", datetime.now(UTC)), 10**6)
        for _ in range(3):
            picture = np.zeros((240, 320, 3), np.uint8)
            stream.recorder.offer(av.VideoFrame.from_ndarray(picture, format="rgb24"))
        await relay.end(stream, "unpublished")

    relay = Relay(on_recorded=drone_gone)
    asyncio.run(publish_and_end())
    # While it was being filed the stream was no longer live, but still ending.
    [(drone_id, organisation_id, frames, health)] = seen
    assert (drone_id, organisation_id, frames) == ("ACME_1", 7, 3)
    assert health["streams"] == 0 and health["streams_ending"] == 1
    assert relay.counts["recordings_drone_gone"] == 1 and relay.counts["recordings"] == 1
    assert relay.health()["streams_ending"] == 0

"""A flight's recorded video plays in the log viewer in step with the plots: the frame shown
at a cursor time is (by the capture time drawn into it, onboard/framecode.py) the last
one captured at or before the cursor, or its neighbour, in headless Chromium against the real ASGI app."""

from __future__ import annotations

import time
from datetime import UTC, datetime

import av
import numpy as np
import pytest
from django.conf import settings
from playwright.sync_api import expect

from livevideo import access
from livevideo.models import VideoRecording
from livevideo.recording import Recorder
from logs.models import FlightLog
from onboard import framecode
from tests.conftest import login
from tests.livevideo.support import assert_in_step
from tests.logs.conftest import upload, wait_until_processed
from tests.logs.test_api import client_for
from tests.logs.test_browser import click_timeline_at
from tests.logs.test_tlog import write_tlog

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]

FPS = 10
FRAMES = 30
LINK_DELAY_MS = 80  # frames reach the ground this long after their capture


def record_stamped_video(drone) -> list[float]:  # type: ignore[no-untyped-def]
    """Record FRAMES frames of `drone` through the ground's recorder as they would arrive,
    each with its capture time drawn in; their capture times (Unix seconds)."""
    path = access.recording_path(drone.drone_id, datetime.now(UTC))
    recorder = Recorder(path, settings.LIVE_VIDEO_RECORDING_MAX_BYTES)
    captured = []
    rgb = np.zeros((240, 320, 3), np.uint8)
    for i in range(FRAMES):
        ms = int(time.time() * 1000) - LINK_DELAY_MS
        rgb[16:] = (i * 8) % 256  # the picture changes from frame to frame
        framecode.stamp(rgb, ms)
        recorder.offer(av.VideoFrame.from_ndarray(rgb, format="rgb24"))
        captured.append(ms / 1000)
        time.sleep(1 / FPS)
    done = recorder.close()
    assert done is not None and done.frames >= FRAMES - 2
    assert access.file_recording(drone.drone_id, drone.organisation_id, done)
    return captured


def file_shifts(path: str) -> dict[int, float]:
    """Each frame's capture time (ms, read from its pixels) and its capture time less its
    time in the file: what a player adds to file time to get capture time."""
    shifts = {}
    with av.open(path) as container:
        for frame in container.decode(video=0):
            luma = frame.to_ndarray(format="yuv420p")[: frame.height]
            ms = framecode.read(luma)
            if ms is not None:
                shifts[ms] = ms / 1000 - float(frame.time)
    return shifts


def test_a_flights_recording_plays_in_the_log_viewer_in_step_with_the_cursor(
    world_tx, worker, live_logs, page, tmp_path
):
    captured = record_stamped_video(world_tx.drone)
    first, last = captured[0], captured[-1]
    recording = VideoRecording.objects.get(drone=world_tx.drone)
    # The telemetry of the same flight, on the same (Unix) clock, from a second before the
    # first frame to a second after the last, at 10 Hz: the recording's span is what the
    # machine made of FRAMES sleeps of 1/FPS, longer when it is busy.
    samples = int((last - first + 2) * 10) + 1
    client = client_for(world_tx.operator)
    created = upload(
        client, write_tlog(tmp_path / "flight.tlog", n=samples, t0_us=int((first - 1) * 1e6))
    ).json()
    info = wait_until_processed(client, created["id"])
    assert info["status"] == "ready"
    FlightLog.objects.filter(pk=created["id"]).update(drone=world_tx.drone)
    listed = client.get(f"/api/v1/logs/{created['id']}/video/").json()["recordings"]
    assert [r["id"] for r in listed] == [recording.pk]

    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")
    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=20_000)
    card = viewer.locator('[data-part="video-card"]')
    expect(card).to_be_visible(timeout=10_000)
    shown = []
    for at in (first + 0.8, last - 0.6):
        click_timeline_at(page, viewer, at, info["start"], info["end"])
        expect(card).to_have_attribute("data-state", "shown", timeout=15_000)
        cursor = page.evaluate("window.logViewers[0].state.cursor")
        frame_s = int(card.get_attribute("data-frame-ms")) / 1000
        assert_in_step(captured, cursor, frame_s)
        shown.append(frame_s)
    assert shown[1] - shown[0] > 1.0  # a later cursor showed a later frame
    # The player measured the link's delay from the capture time drawn into the frame it
    # shows: its shift from file time to capture time is that frame's in the file, and the
    # recording's start less it is the frame's delay (at least the link's).
    shift = page.evaluate("window.logViewers[0].video.current.shift")
    assert abs(shift - file_shifts(recording.file.path)[round(shown[1] * 1000)]) < 0.01
    assert LINK_DELAY_MS / 1000 <= recording.started_at.timestamp() - shift + 0.001 < 1.0

    # Outside the recording, the viewer says there is no video rather than a wrong frame.
    click_timeline_at(page, viewer, first - 0.7, info["start"], info["end"])
    expect(card).to_have_attribute("data-state", "outside")

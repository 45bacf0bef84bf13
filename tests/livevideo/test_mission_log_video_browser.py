"""The mission log viewer plays the recordings of the mission's flights in step with its
time cursor and its map: the frame shown at a cursor time is (by the capture time drawn
into it) the last one captured at or before the cursor, or its neighbour; replaying moves
the cursor and plays the video; outside the recording the card says there is no video."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest
from playwright.sync_api import expect

from livevideo.models import VideoRecording
from missions.models import Event, Mission
from records.models import FlightRecord, Origin
from tests.conftest import login
from tests.livevideo.support import assert_in_step
from tests.logs.test_api import client_for
from tests.logs.test_video_playback_browser import record_stamped_video

pytestmark = [pytest.mark.browser, pytest.mark.e2e]

LAT, LON = 40.6303, -8.6575


def at(ts: float) -> datetime:
    return datetime.fromtimestamp(ts, UTC)


def flown_mission(world, first: float, last: float) -> tuple[Mission, list[tuple[float, float]]]:  # type: ignore[no-untyped-def]
    """ACME_1 flies north from a second before the recording to a second after it, a step
    event about every half second, on the flight record tied to the mission; the mission
    and its (time, latitude) reports."""
    mission = Mission.objects.create(organisation=world.org, name="filmed", status="completed")
    start, end = first - 1.0, last + 1.0
    n = int((end - start) / 0.5) + 1
    reports = []
    for i in range(n):
        ts = start + (end - start) * i / (n - 1)
        reports.append((ts, LAT + i * 1e-4))
        Event.objects.create(
            mission=mission, drone=world.drone, kind=Event.Kind.STEP, at=at(ts),
            data={"ts": ts, "index": i, "status": "completed",
                  "position": {"lat": LAT + i * 1e-4, "lon": LON, "alt": 15}},
        )  # fmt: skip
    FlightRecord.objects.create(
        organisation=world.org, drone=world.drone, drone_ident="ACME_1",
        origin=Origin.MISSION, mission=mission, started_at=at(start), ended_at=at(end),
        duration_s=end - start,
    )  # fmt: skip
    return mission, reports


def set_cursor(page, t: float) -> None:  # type: ignore[no-untyped-def]
    page.evaluate(
        """t => { const s = document.querySelector('#log-time [data-part="cursor"]');
        s.value = String(t - window.skyhiveLogViewer.time.state.start);
        s.dispatchEvent(new Event('input', { bubbles: true })); }""",
        t,
    )


def test_the_mission_log_viewer_plays_its_flights_video_in_step(world_tx, live_asgi, page):  # type: ignore[no-untyped-def]
    captured = record_stamped_video(world_tx.drone)
    first, last = captured[0], captured[-1]
    recording = VideoRecording.objects.get(drone=world_tx.drone)
    # The recording ends when its recorder closes it, which a loaded machine may do well
    # after the last frame: the flight lasts past both, so the cursor can leave it.
    ended = max(last, recording.ended_at.timestamp())
    mission, reports = flown_mission(world_tx, first, ended)
    # A recording of the same drone outside the mission's flight is not the mission's.
    VideoRecording.objects.create(
        drone=world_tx.drone, started_at=at(first - 3600), ended_at=at(first - 3500),
        file=recording.file.name, size=recording.size, frames=10, width=320, height=240,
    )  # fmt: skip
    listed = client_for(world_tx.viewer).get(f"/api/v1/missions/{mission.pk}/video/").json()
    assert [r["id"] for r in listed["recordings"]] == [recording.pk]
    outsider = client_for(world_tx.outsider).get(f"/api/v1/missions/{mission.pk}/video/")
    assert outsider.status_code == 404

    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/missions/log-viewer/?mission={mission.pk}")
    expect(page.locator("#log-time")).to_have_attribute("data-videos", "1", timeout=15_000)
    card = page.locator('#log-time [data-part="video-card"][data-drone="ACME_1"]')
    expect(card).to_be_visible()
    shown = []
    for t in (first + 0.8, last - 0.6):
        set_cursor(page, t)
        expect(card).to_have_attribute("data-state", "shown", timeout=15_000)
        cursor = page.evaluate("window.skyhiveLogViewer.time.state.cursor")
        frame_s = int(card.get_attribute("data-frame-ms")) / 1000
        assert_in_step(captured, cursor, frame_s)
        shown.append(frame_s)
        # The map's drone is where the mission's events put it at the cursor.
        lat = page.evaluate("window.skyhiveLogViewer.time.markers.get('ACME_1').getLatLng().lat")
        assert abs(lat - np.interp(cursor, *zip(*reports, strict=True))) < 1e-7
    assert shown[1] - shown[0] > 1.0

    # Replaying from the start of the recording: the cursor moves and the video plays.
    set_cursor(page, first + 0.1)
    expect(card).to_have_attribute("data-state", "shown", timeout=15_000)
    page.click('#log-time [data-action="play"]')
    expect(card).to_have_attribute("data-state", "playing", timeout=5_000)
    page.wait_for_function(
        f"window.skyhiveLogViewer.time.state.cursor > {first + 1.0}", timeout=10_000
    )
    page.wait_for_function(
        "(() => { const v = document.querySelector('#log-time video');"
        " return !v.paused && v.currentTime > 0.5; })()",
        timeout=10_000,
    )
    page.click('#log-time [data-action="play"]')

    # Past the recording's end the card says there is no video.
    set_cursor(page, ended + 0.9)
    expect(card).to_have_attribute("data-state", "outside")
    assert card.locator('[data-part="video-caption"]').inner_text() == "No video at this time."

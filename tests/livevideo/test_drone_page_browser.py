"""Two simulated drones (the flight-controller simulator and the real agent, with its
camera published to the media server) stream; each drone page plays its drone's video,
whose frames move on, with the measured delay, resolution and bitrate shown, and the
video wall shows both at once; teleoperation's page shows the live video while it
comes and says it is on the past view when it stops, and the stopped stream's recording
plays on the flight's record; an operator takes a still from the stream. A member of
another organisation gets neither the stream's state nor a viewer session."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from fleet.models import Drone
from tests.conftest import login
from tests.onboard.ground import start_agent
from tests.support.live import LiveServer
from workers.broker.credentials import stored_hash
from workers.mosquitto import start_broker

from .support import MediaServer, wait_until

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRONES = ("ACME_1", "ACME_2")
HOME = (40.6303, -8.6575, 12.0)


@pytest.fixture
def ground(world_tx, tmp_path: Path):  # type: ignore[no-untyped-def]
    from django.db import connection

    from tests import factories

    factories.drone(world_tx.org, "ACME_2")
    passwords = {drone_id: f"{drone_id.lower()}-password" for drone_id in DRONES}
    for drone_id, password in passwords.items():
        Drone.objects.filter(drone_id=drone_id).update(mqtt_password_hash=stored_hash(password))
    database = connection.settings_dict["NAME"]
    media = MediaServer(database)
    # A generous bound for teleoperation's live view on a loaded test machine: the switch
    # to the past view is tried by stopping a drone's stream.
    web = LiveServer(
        database, {"LIVE_VIDEO_URL": media.url, "LIVE_VIDEO_TELEOP_MAX_DELAY_MS": "60000"}
    )
    broker = start_broker(tmp_path / "broker", {"ground": "pw", **passwords})
    running = []
    agents = {}
    try:
        for drone_id in DRONES:
            folder = tmp_path / drone_id
            folder.mkdir()
            sim = start_simulator(
                home=HOME, time_scale=1.0, arming_line=folder / "arming_line",
                log_file=folder / "sim.log",
            )  # fmt: skip
            running.append(sim)
            agents[drone_id] = start_agent(
                    folder, drone_id=drone_id, link=sim.url,
                    broker_url=broker.url_for(drone_id), arming_line=folder / "arming_line",
                    time_scale=1.0, extra=["--media-url", media.drone_url, "--live-fps", "5"],
            )  # fmt: skip
            running.append(agents[drone_id])
        for drone_id in DRONES:
            wait_until(lambda d=drone_id: media.get(f"/streams/{d}").get("frames", 0) > 3, 60)
        web.agents = agents
        yield web
    finally:
        for process in reversed(running):
            process.stop()
        broker.stop()
        web.stop()
        media.stop()


def playing(page, drone_id: str, frames: int = 10) -> dict:  # type: ignore[no-untyped-def]
    card = page.locator("#live-video")
    page.wait_for_function(
        f"Number(document.querySelector('#live-video').dataset.frames || 0) > {frames}",
        timeout=30_000,
    )
    return {
        "captured": int(card.get_attribute("data-captured")),
        "delay": page.locator('[data-video="delay"]').inner_text(),
        "resolution": page.locator('[data-video="resolution"]').inner_text(),
    }


def test_each_drone_page_plays_its_live_video_with_its_delay(ground, world_tx, page, browser):  # type: ignore[no-untyped-def]
    login(page, ground, world_tx.operator.username)
    second = page.context.new_page()
    page.goto(f"{ground.url}/drones/{DRONES[0]}/")
    second.goto(f"{ground.url}/drones/{DRONES[1]}/")
    for tab in (page, second):
        first = playing(tab, "", 5)
        time.sleep(1.0)
        later = playing(tab, "", int(tab.locator("#live-video").get_attribute("data-frames")))
        # Frames move on: the capture time drawn into the picture advances.
        assert later["captured"] > first["captured"]
        assert re.fullmatch(r"\d+ ms", later["delay"]), later
        assert int(later["delay"].split()[0]) < 5000
        # The publisher's size, or its half: on a test machine so loaded that round trips
        # on loopback stay 0.2 s over their least, the picture narrows as on a queueing
        # link (onboard/video_adaptation.py).
        assert later["resolution"] in ("320 × 240", "160 × 120")
        tab.wait_for_function(
            "Number(document.querySelector('#live-video').dataset.bitrateKbps || 0) > 0",
            timeout=10_000,
        )
        assert tab.locator('[data-video="state"]').inner_text() == "playing"
        # Both drones at once: each page shows its own drone.
        video = tab.evaluate(
            "(() => { const v = document.querySelector('video'); return [v.videoWidth, v.paused]; })()"
        )
        assert video in ([320, False], [160, False])
    state = page.request.get(f"{ground.url}/api/v1/drones/{DRONES[1]}/video/").json()
    assert state["live"] and (state["width"], state["height"]) in ((320, 240), (160, 120))
    assert state["bitrate_bps"] > 0 and state["delay_ms"] is not None
    second.close()

    # The video wall shows both drones at once, each playing.
    wall = page.context.new_page()
    wall.goto(f"{ground.url}/video/")
    wall.wait_for_function(
        "[...document.querySelectorAll('[data-live-video]')].length === 2 && "
        "[...document.querySelectorAll('[data-live-video]')]"
        ".every(card => Number(card.dataset.frames || 0) > 5)",
        timeout=60_000,
    )
    tiles = wall.locator("[data-live-video]")
    assert [tiles.nth(i).get_attribute("data-drone") for i in range(2)] == list(DRONES)
    wall.close()

    # Teleoperation on the past view page: live video while it is fresh, the past view
    # (said on screen) once the drone's stream stops.
    teleop = page.context.new_page()
    teleop.goto(f"{ground.url}/pastview/{DRONES[1]}/")
    teleop.wait_for_function(
        "document.querySelector('#pv-live-video').dataset.view === 'live'", timeout=30_000
    )
    mode = teleop.locator('#pv-live-video [data-video="mode"]')
    assert mode.inner_text().startswith("Teleoperating on live video, ")
    assert teleop.locator("#pv-live-video video").is_visible()
    ground.agents[DRONES[1]].stop()
    teleop.wait_for_function(
        "document.querySelector('#pv-live-video').dataset.view === 'past'", timeout=15_000
    )
    assert mode.inner_text() == "No live video: teleoperating on the past view"
    assert not teleop.locator("#pv-live-video video").is_visible()
    teleop.close()

    # That stream was recorded on the ground and plays on the record of the flight.
    from datetime import UTC, datetime, timedelta

    from livevideo.models import VideoRecording
    from records.models import FlightRecord, Origin

    wait_until(lambda: VideoRecording.objects.filter(drone__drone_id=DRONES[1]).exists(), 30)
    start = datetime.now(UTC) - timedelta(minutes=10)
    flight = FlightRecord.objects.create(
        organisation=world_tx.org, drone=Drone.objects.get(drone_id=DRONES[1]),
        drone_ident=DRONES[1], origin=Origin.COMMAND, started_at=start,
        ended_at=start + timedelta(minutes=11), duration_s=660.0,
    )  # fmt: skip
    record = page.context.new_page()
    record.goto(f"{ground.url}/records/flights/{flight.pk}/")
    record.wait_for_function(
        "(() => { const v = document.querySelector('#flight-video video');"
        " return v && v.readyState >= 2 && v.videoWidth === 320; })()",
        timeout=15_000,
    )
    record.close()

    # A still from the stream, stored and linked from the page.
    page.click("[data-video-still]")
    page.wait_for_selector('[data-video="still"][data-still-id]', timeout=15_000)
    still = page.locator('[data-video="still"]')
    assert still.inner_text().startswith("Still taken at")
    assert (
        page.request.get(ground.url + still.get_attribute("href")).headers["content-type"]
        == "image/jpeg"
    )

    # A member of another organisation: no state, no viewer session, no player.
    outsider = browser.new_context(bypass_csp=True).new_page()
    login(outsider, ground, world_tx.outsider.username)
    assert outsider.request.get(f"{ground.url}/api/v1/drones/{DRONES[0]}/video/").status == 404
    token = outsider.context.cookies()
    csrf = next(c["value"] for c in token if c["name"] == "csrftoken")
    refused = outsider.request.post(
        f"{ground.url}/api/v1/drones/{DRONES[0]}/video/whep/",
        data="v=0\r\n",
        headers={"Content-Type": "application/sdp", "X-CSRFToken": csrf},
    )
    assert refused.status == 404
    outsider.goto(f"{ground.url}/drones/{DRONES[0]}/")
    assert outsider.locator("#live-video").count() == 0
    outsider.goto(f"{ground.url}/video/")
    assert outsider.locator("[data-live-video]").count() == 0
    outsider.context.close()

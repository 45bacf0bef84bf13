"""The mission page plays the live stream of the drone selected (on its map or in its drone
list) with its age, through the drone's own video endpoint: a drone that does not stream
is said to be so, and why (offline, or online and not publishing), and a member of another
organisation gets no state and no viewer session from that endpoint."""

from __future__ import annotations

import re

import pytest
from django.db import connection
from django.utils import timezone
from playwright.sync_api import expect

from fleet.models import Drone
from missions.models import Assignment, Mission
from onboard.live_video import LiveVideoConfig
from tests import factories
from tests.conftest import login
from tests.support.live import LiveServer
from workers.broker.credentials import stored_hash

from .support import MediaServer, Publisher, wait_until

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

PASSWORD = "acme_1-password"


@pytest.fixture
def streaming(world_tx):  # type: ignore[no-untyped-def]
    """ACME_1 publishes its camera to a real media server; ACME_2 does not stream."""
    factories.drone(world_tx.org, "ACME_2")
    Drone.objects.filter(drone_id="ACME_1").update(mqtt_password_hash=stored_hash(PASSWORD))
    for i, drone_id in enumerate(("ACME_1", "ACME_2")):
        Drone.objects.filter(drone_id=drone_id).update(
            online=True, last_seen=timezone.now(), lat=40.6303 + i * 0.0004, lon=-8.6575, alt=15
        )
    media = MediaServer(connection.settings_dict["NAME"])
    web = LiveServer(connection.settings_dict["NAME"], {"LIVE_VIDEO_URL": media.url})
    publisher = Publisher(LiveVideoConfig(media.drone_url, "ACME_1", PASSWORD, fps=5))
    try:
        wait_until(lambda: media.get("/streams/ACME_1").get("frames", 0) > 3, 60)
        yield web
    finally:
        publisher.stop()
        web.stop()
        media.stop()


def test_the_mission_page_plays_the_selected_drones_stream(streaming, world_tx, page, browser):  # type: ignore[no-untyped-def]
    mission = Mission.objects.create(organisation=world_tx.org, name="two", status="running")
    for drone in Drone.objects.filter(drone_id__in=("ACME_1", "ACME_2")):
        Assignment.objects.create(
            mission=mission, drone=drone, step_indexes=[], status=Assignment.Status.ACCEPTED
        )
    Drone.objects.filter(drone_id="ACME_2").update(online=False)
    login(page, streaming, world_tx.viewer.username)
    page.goto(f"{streaming.url}/missions/{mission.pk}/")
    card = page.locator("#mission-video")
    why = card.locator('[data-video="why"]')
    assert card.get_attribute("data-state") is None  # nothing plays before a drone is chosen

    # ACME_1, chosen on the map, plays with its age.
    page.locator('.leaflet-marker-icon[title="ACME_1"]').click()
    page.wait_for_function(
        "Number(document.querySelector('#mission-video').dataset.frames || 0) > 5",
        timeout=30_000,
    )
    assert card.get_attribute("data-video-url") == "/api/v1/drones/ACME_1/video/"
    assert card.get_attribute("data-state") == "playing"
    assert re.fullmatch(r"\d+ ms", card.locator('[data-video="delay"]').inner_text())
    # The picture's size may follow the link: any size the stream has is shown.
    assert re.fullmatch(r"\d+ × \d+", card.locator('[data-video="resolution"]').inner_text())
    assert why.inner_text() == ""
    assert "selected" in (
        page.locator('#progress-list [data-drone="ACME_1"]').get_attribute("class") or ""
    )
    first = int(card.get_attribute("data-captured"))
    page.wait_for_function(
        f"Number(document.querySelector('#mission-video').dataset.captured) > {first}",
        timeout=10_000,
    )

    # ACME_2, chosen in the list, has no stream: the player leaves ACME_1's and says why.
    page.locator('#progress-list [data-drone="ACME_2"]').click()
    expect(card).to_have_attribute("data-state", "not streaming", timeout=15_000)
    expect(why).to_have_text("This drone is offline.")
    assert card.get_attribute("data-frames") is None
    Drone.objects.filter(drone_id="ACME_2").update(online=True)
    expect(why).to_have_text(
        "This drone is online but is not streaming live video now.", timeout=10_000
    )

    # The endpoint the page uses gives another organisation neither state nor session.
    outsider = browser.new_context(bypass_csp=True).new_page()
    login(outsider, streaming, world_tx.outsider.username)
    assert outsider.request.get(f"{streaming.url}/api/v1/drones/ACME_1/video/").status == 404
    csrf = next(c["value"] for c in outsider.context.cookies() if c["name"] == "csrftoken")
    refused = outsider.request.post(
        f"{streaming.url}/api/v1/drones/ACME_1/video/whep/",
        data="v=0\r\n",
        headers={"Content-Type": "application/sdp", "X-CSRFToken": csrf},
    )
    assert refused.status == 404
    assert outsider.goto(f"{streaming.url}/missions/{mission.pk}/").status == 404
    outsider.context.close()

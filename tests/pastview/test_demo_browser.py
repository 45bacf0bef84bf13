"""The past view as `make run DRONES=1` shows it: a simulated drone (flight-controller
simulator and the real onboard agent, started with run_simulated_drones' default streams)
sends camera frames and poses; the page counts this drone's frames, shows the live
picture once frames arrive, and offers teleoperation only while they keep arriving."""

from __future__ import annotations

from pathlib import Path

import pytest

from firmware.sim.fleet import start_drone
from fleet.management.commands.run_simulated_drones import Command, streaming_args
from tests.conftest import login

from .support import ServiceThread
from .test_e2e import broker  # noqa: F401, F811 - the drone and the ground share this broker

pytestmark = [
    pytest.mark.browser,
    pytest.mark.e2e,
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]

DRONE = "ACME_1"  # the world's drone, so the portal knows it
HOME = (40.6303, -8.6575, 12.0)


def demo_agent_args() -> list[str]:
    """The agent flags `make run DRONES=N` gives each simulated drone."""
    options = Command().create_parser("manage.py", "run_simulated_drones").parse_args(["1"])
    assert options.video_rate > 0 and options.pose_rate > 0  # streaming is the default
    return streaming_args(options.video_rate, options.pose_rate)


@pytest.fixture
def demo_drone(tmp_path: Path, broker, world_tx):  # noqa: F811
    service = ServiceThread(broker.url_for("ground"))
    drone = start_drone(
        tmp_path / "drone", DRONE, broker.url_for(DRONE), HOME,
        time_scale=1.0, agent_args=demo_agent_args(),
    )  # fmt: skip
    yield drone
    drone.stop()
    service.stop()


# The page's state when its scripts have run and before any socket message can arrive
# (messages are later tasks than DOMContentLoaded).
RECORD_FIRST_STATE = """
document.addEventListener("DOMContentLoaded", () => {
  const byId = (id) => document.getElementById(id);
  window.firstState = {
    control: byId("pv-control").disabled,
    liveBox: byId("pv-live-box").hidden,
    showLive: byId("pv-show-live").disabled,
  };
});
"""


def counter(page, key: str) -> str:  # type: ignore[no-untyped-def]
    return page.locator(f'#pv-status dd[data-key="{key}"]').inner_text()


def test_the_demo_drone_streams_and_teleoperation_follows_the_frames(demo_drone, live_asgi, page):
    login(page, live_asgi, "operator")
    page.add_init_script(RECORD_FIRST_STATE)
    page.goto(f"{live_asgi.url}/pastview/{DRONE}/")
    button = page.locator("#pv-control")
    # Before anything from the drone (its frames may arrive a moment after the page loads).
    first = page.evaluate("window.firstState")
    assert first == {"control": True, "liveBox": True, "showLive": True}

    # Frames and tracked poses arrive: this drone's counters grow, the view is drawn.
    page.wait_for_function(
        "document.querySelector('#pv-status dd[data-key=frames_received]').textContent > 0",
        timeout=30_000,
    )
    page.wait_for_function(
        "window.pastview.frame !== null && window.pastview.tracking === 'tracked'"
    )
    # The counters are redrawn with each status message (every 2 s), which may come
    # before the first pose did.
    page.wait_for_function(
        "document.querySelector('#pv-status dd[data-key=poses_received]').textContent > 0",
        timeout=30_000,
    )
    assert page.locator("#pv-warning").is_hidden()
    # The status row of the last camera frame is redrawn with the next status message.
    page.wait_for_function(
        "document.querySelector('#pv-status dd[data-key=live_age]').textContent.endsWith('s ago')"
    )

    # The live camera is offered once a frame came, and shows a real picture.
    page.check("#pv-show-live")
    page.wait_for_function("document.getElementById('pv-live').naturalWidth > 0")
    assert page.locator("#pv-live-box").is_visible()

    page.wait_for_function("!document.getElementById('pv-control').disabled")
    button.click()
    assert button.get_attribute("aria-pressed") == "true"

    # The drone stops sending (its agent ends): control is released and no longer offered.
    demo_drone.agent.stop(10)
    page.wait_for_function("document.getElementById('pv-control').disabled", timeout=10_000)
    assert button.get_attribute("aria-pressed") == "false"
    assert "No camera frame" in page.locator("#pv-teleop-reason").inner_text()
    assert "Control released" in page.locator("#pv-teleop-message").inner_text()

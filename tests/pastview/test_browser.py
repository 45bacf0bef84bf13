"""The past-view page in headless Chromium: frames and poses from a drone over MQTT, through
the service and the live ASGI server, drawn with WebGL over the chosen frame."""

from __future__ import annotations

import base64
import io
import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.conftest import login
from workers.mosquitto import start_broker

from .support import DronePublisher, ServiceThread, level

pytestmark = [
    pytest.mark.browser,
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]

DRONE = "ACME_1"


@pytest.fixture
def broker(tmp_path: Path):
    b = start_broker(tmp_path, {"ground": "pw", DRONE: "dpw"})
    yield b
    b.stop()


@pytest.fixture
def service(broker, world_tx):
    running = ServiceThread(broker.url_for("ground"))
    yield running
    running.stop()


class Streaming:
    """A drone sending a frame and a (slightly moving) pose every 0.2 s, as the agent does:
    teleoperation is offered only while such a stream is fresh."""

    def __init__(self, drone: DronePublisher, yaw_deg: float = 90.0) -> None:
        self.stop_event = threading.Event()

        def run() -> None:
            n = 0
            while not self.stop_event.wait(0.2):
                n += 1
                t = time.time()
                drone.frame(t, [0.0, 0.0, -10.0], level(yaw_deg))
                drone.poses((t + 0.01, [0.0, 2.5 + 0.001 * (n % 2), -10.0], level(yaw_deg)))

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.stop_event.set()
        self.thread.join(5)


def canvas_colours(page) -> dict[str, int]:  # type: ignore[no-untyped-def]
    """Pixels of the drone's red and green sides in the WebGL canvas (not the photo under it)."""
    url = page.evaluate("document.getElementById('pv-canvas').toDataURL('image/png')")
    image = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGBA")
    r, g, b, a = np.asarray(image).astype(int).transpose(2, 0, 1)
    drawn = a >= 200
    counts = {
        "drawn": int(drawn.sum()),
        "red": int((drawn & (r > 200) & (g < 60) & (b < 60)).sum()),
        "green": int((drawn & (g > 200) & (r < 60) & (b < 60)).sum()),
    }
    return counts


def test_the_view_draws_the_drone_over_the_chosen_frame_and_warns_when_tracking_is_lost(
    service, broker, live_asgi, page, tmp_path: Path
):
    drone = DronePublisher(broker.port, DRONE, "dpw")
    try:
        login(page, live_asgi, "operator")
        page.goto(f"{live_asgi.url}/pastview/{DRONE}/")
        page.wait_for_function("window.pastview.socket && window.pastview.socket.readyState === 1")
        service.wait_until_watched(DRONE)
        assert page.locator("#pv-warning").inner_text() == "No frame yet"
        assert canvas_colours(page)["drawn"] == 0

        # A frame taken 2.5 m behind and 1 m above the drone: the top with its red/green
        # arrow and the box show.
        t0 = time.time()
        drone.frame(t0, [0.0, 0.0, -11.0], level(0.0))
        drone.poses((t0 + 0.1, [2.5, 0.0, -10.0], level(0.0)))
        page.wait_for_function("window.pastview.frame !== null && window.pastview.updates > 0")
        page.wait_for_function("document.getElementById('pv-frame').complete")
        assert page.locator("#pv-warning").is_hidden()
        assert page.locator("#pv-tracking").inner_text() == "tracked"
        colours = canvas_colours(page)
        assert colours["red"] > 50 and colours["green"] > 50, colours
        page.locator("#pv-stage").screenshot(path=str(tmp_path / "pastview.png"))
        # The box sits in the upper middle: straight ahead, 1 m below the camera's level
        # while the camera looks 30 degrees down.
        assert colours["drawn"] < 0.2 * 640 * 480

        drone.poses(
            (t0 + 0.2, [2.5, 0.0, -10.0], level(0.0)), (t0 + 0.3, [2.5, 0.0, -10.0], level(0.0))
        )
        page.wait_for_function("window.pastview.tracking === 'lost'")
        assert "Tracking lost" in page.locator("#pv-warning").inner_text()
        assert page.evaluate("window.pastview.beeps") == 1
        drone.poses((t0 + 0.4, [2.6, 0.0, -10.0], level(0.0)))
        page.wait_for_function("window.pastview.tracking === 'tracked'")
        assert page.locator("#pv-warning").is_hidden()
    finally:
        drone.close()


def test_a_viewer_gets_the_view_without_controls(service, live_asgi, page):
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/pastview/{DRONE}/")
    page.wait_for_function("window.pastview.socket && window.pastview.socket.readyState === 1")
    assert page.locator("#pv-canvas").is_visible()
    assert page.locator("#pv-control").count() == 0
    assert page.locator("#pv-save").is_disabled()


def test_an_operator_flies_by_keyboard_and_edits_the_evaluation_function(
    service, broker, live_asgi, page
):
    drone = DronePublisher(broker.port, DRONE, "dpw")
    try:
        login(page, live_asgi, "operator")
        page.goto(f"{live_asgi.url}/pastview/{DRONE}/")
        page.wait_for_function("window.pastview.socket && window.pastview.socket.readyState === 1")
        service.wait_until_watched(DRONE)
        t0 = time.time()
        drone.frame(t0, [0.0, 0.0, -10.0], level(90.0))
        drone.poses((t0 + 0.1, [0.0, 2.5, -10.0], level(90.0)))
        page.wait_for_function("window.pastview.updates > 0")

        sent = []
        page.on("websocket", lambda ws: ws.on("framesent", lambda payload: sent.append(payload)))
        page.reload()
        page.wait_for_function("window.pastview.socket && window.pastview.socket.readyState === 1")
        stream = Streaming(drone)
        page.wait_for_function("!document.getElementById('pv-control').disabled")
        page.click("#pv-control")
        assert page.locator("#pv-control").get_attribute("aria-pressed") == "true"
        page.keyboard.down("KeyW")
        # The world's drone is offline: the Drone Manager's refusal shows on the page.
        page.wait_for_function(
            "document.getElementById('pv-teleop-message').textContent.includes('offline')"
        )
        page.keyboard.up("KeyW")
        moves = sent_until(page, sent, lambda moves: moves[-1] == {"type": "stop"})
        assert {"type": "teleop", "forward": 1, "right": 0, "up": 0} in moves

        page.select_option("#pv-function", "murata")
        page.fill("#pv-params input[name=coeff_tilt]", "3")
        page.click("#pv-save")
        page.wait_for_function(
            "document.getElementById('pv-settings-message').textContent.startsWith('Applied')"
        )
        page.check("#pv-show-live")
        assert page.locator("#pv-live").get_attribute("src").startswith("data:image/jpeg")
        stream.stop()
    finally:
        drone.close()

    from pastview.models import ViewSettings

    stored = ViewSettings.objects.get(drone__drone_id=DRONE).settings["evaluation"]
    assert stored["function"] == "murata" and stored["coeff_tilt"] == 3.0


def test_a_gamepad_stick_flies_and_letting_go_or_leaving_the_page_stops(
    service, broker, live_asgi, page
):
    # Headless Chromium has no gamepad: stand one in for the browser's Gamepad API.
    page.add_init_script(
        "window.stick = [0, 0, 0, 0];"
        "navigator.getGamepads = () => [{connected: true, axes: window.stick}];"
    )
    sent = []
    page.on("websocket", lambda ws: ws.on("framesent", lambda payload: sent.append(payload)))
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/pastview/{DRONE}/")
    page.wait_for_function("window.pastview.socket && window.pastview.socket.readyState === 1")
    service.wait_until_watched(DRONE)
    drone = DronePublisher(broker.port, DRONE, "dpw")
    stream = Streaming(drone)
    try:
        fly_by_gamepad(page, sent)
    finally:
        stream.stop()
        drone.close()


def sent_until(page, sent: list, holds, timeout: float = 10.0) -> list[dict]:  # type: ignore[no-untyped-def]
    """The frames the page sent, once `holds(them)`. The page reads the stick four times a
    second (PASTVIEW_TELEOP_HZ); 10 s is forty reads, for a loaded machine."""
    deadline = time.monotonic() + timeout
    while True:
        moves = [json.loads(p) for p in sent]
        if moves and holds(moves):
            return moves
        assert time.monotonic() < deadline, f"the page never sent that: {moves[-5:]}"
        page.wait_for_timeout(50)  # lets Playwright deliver the socket's frames


def fly_by_gamepad(page, sent: list) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function("!document.getElementById('pv-control').disabled")
    page.click("#pv-control")
    page.evaluate("window.stick[0] = 0.5; window.stick[1] = -1.0")  # half right, full forward
    sent_until(page, sent, lambda m: {"type": "teleop", "forward": 1, "right": 0.5, "up": 0} in m)
    page.evaluate("window.stick[0] = 0.05; window.stick[1] = 0.1")  # inside the dead zone
    sent_until(page, sent, lambda m: m[-1] == {"type": "stop"})
    # Back on the stick, then the window loses focus with the stick still held: one stop,
    # and nothing after it until the page has the focus again.
    page.evaluate("window.stick[1] = -1.0")
    sent_until(page, sent, lambda m: m[-1]["type"] == "teleop")
    page.evaluate("window.dispatchEvent(new Event('blur'))")
    sent_until(page, sent, lambda m: m[-1] == {"type": "stop"})
    count = len(sent)
    page.wait_for_timeout(700)  # nearly three reads of the stick, still held
    assert json.loads(sent[-1]) == {"type": "stop"} and len(sent) == count
    page.evaluate("window.dispatchEvent(new Event('focus'))")
    sent_until(page, sent, lambda m: m[-1]["type"] == "teleop")

"""The Logs pages in headless Chromium against the real ASGI app, websocket and worker."""

from __future__ import annotations

import json
import re
from concurrent.futures import ThreadPoolExecutor
from urllib.parse import parse_qs, urlparse

import numpy as np
import pytest
from playwright.sync_api import expect

from logs.synth import synthetic_dataflash, synthetic_ulog
from tests.conftest import login
from tests.logs.conftest import upload, wait_until_processed
from tests.logs.dfi_builder import write_dfi
from tests.logs.test_api import client_for

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]


def click_timeline_at(page, viewer, seconds: float, start: float, end: float) -> None:  # type: ignore[no-untyped-def]
    """Click the timeline where `seconds` lies, from the lane geometry timeline.js draws."""
    canvas = viewer.locator('[data-part="timeline-canvas"]')
    box = canvas.bounding_box()
    label = min(
        110 if "lv-compact" in (viewer.get_attribute("class") or "") else 150,
        round(box["width"] * 0.28),
    )
    lane = box["width"] - label - 8
    x = label + (seconds - start) / (end - start) * lane
    canvas.click(position={"x": x, "y": box["height"] - 10})


def test_an_uploaded_log_shows_progress_and_the_tree_reads_the_value_at_a_clicked_time(
    world_tx, worker, live_logs, page, tmp_path
):
    login(page, live_logs, "operator")
    page.goto(f"{live_logs.url}/logs/")
    page.set_input_files("#log-file", str(write_dfi(tmp_path / "hover-test.dfi")))

    item = page.locator("#uploads li").first
    expect(item.locator("progress")).to_be_visible()
    expect(item).to_contain_text("Ready", timeout=30_000)
    item.get_by_role("link", name="open the log").click()

    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)
    # navdata samples at 1, 2 and 3 ms (board time); the log spans 1 to 6 ms.
    click_timeline_at(page, viewer, 0.0027, 0.001, 0.006)
    expect(viewer.locator('[data-part="clock"]')).to_have_text("t = 00:00.002")
    altitude = viewer.locator('[data-path="navdata/Altitude"] .v')
    expect(altitude).to_have_attribute("data-value", "0.75")
    expect(altitude).to_contain_text("m")
    expect(viewer.locator('[data-path="navdata/state"] .v')).to_contain_text("(Flying)")
    # The quick plots and the multi-plot drew from the series endpoint.
    expect(viewer.locator('[data-quick="altitude"] canvas')).to_have_count(1)
    expect(viewer.locator('[data-quick="battery"]')).to_contain_text("No battery in this log")
    if shots := __import__("os").environ.get("LOGS_SCREENSHOTS"):
        page.screenshot(path=f"{shots}/viewer.png", full_page=True)


def test_a_log_that_cannot_be_read_says_why_on_its_page(
    world_tx, worker, live_logs, page, tmp_path
):
    bad = tmp_path / "broken.ulg"
    bad.write_bytes(b"garbage" * 100)
    created = upload(client_for(world_tx.operator), bad).json()
    wait_until_processed(client_for(world_tx.operator), created["id"])
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")
    alert = page.get_by_role("alert")
    expect(alert).to_be_visible()
    expect(alert).to_contain_text("not a valid PX4 ULog")


def test_two_logs_open_side_by_side_with_linked_cursors(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    ulog = tmp_path / "long.ulg"
    synthetic_ulog(ulog, seconds=20)
    ids = []
    for path in (ulog, write_dfi(tmp_path / "short.dfi")):
        created = upload(client, path).json()
        assert wait_until_processed(client, created["id"])["status"] == "ready"
        ids.append(created["id"])

    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/compare/?ids={','.join(ids)}")
    viewers = page.locator("[data-log-viewer]")
    expect(viewers).to_have_count(2)
    for i in range(2):
        expect(viewers.nth(i)).to_have_attribute("data-loaded", "true", timeout=15_000)
    first, second = viewers.nth(0), viewers.nth(1)
    expect(first.locator('[data-part="map-title"]')).to_have_text("Map")

    info = client.get(f"/api/v1/logs/{ids[1]}/").json()
    click_timeline_at(page, second, 0.0025, info["start"], info["end"])
    expect(second.locator('[data-path="navdata/Altitude"] .v')).to_have_attribute(
        "data-value", "0.75"
    )
    if shots := __import__("os").environ.get("LOGS_SCREENSHOTS"):
        page.screenshot(path=f"{shots}/compare.png", full_page=True)
    # The linked cursor moved the long log to the same time since its start.
    expect(first.locator('[data-part="clock"]')).to_have_text(
        second.locator('[data-part="clock"]').inner_text()
    )


def test_zoom_requeries_series_by_range_and_replay_plays_only_the_selection(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    path = tmp_path / "replay.ulg"
    synthetic_ulog(path, seconds=20)
    created = upload(client, path).json()
    info = wait_until_processed(client, created["id"])
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")
    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)
    # The health report above the timeline is read on its own: once it is in, the
    # timeline stays where it is for the pointer's absolute positions below.
    health = viewer.locator('[data-part="health"]')
    expect(health).to_have_attribute("data-loaded", "true", timeout=15_000)
    canvas = viewer.locator('[data-part="timeline-canvas"]')
    box = canvas.bounding_box()

    with page.expect_request(lambda r: "/series/" in r.url and "start=" in r.url) as request:
        # hover waits until the canvas stands still (the panels below it still load) and
        # puts the pointer over it there.
        canvas.hover(position={"x": box["width"] / 2, "y": 60})
        page.mouse.wheel(0, -800)
    query = parse_qs(urlparse(request.value.url).query)
    start, end = float(query["start"][0]), float(query["end"][0])
    assert info["start"] < start < end < info["end"]
    assert end - start < (info["end"] - info["start"]) / 2
    assert 100 <= int(query["points"][0]) <= 4000

    box = canvas.bounding_box()  # where the canvas stands now
    page.mouse.move(box["x"] + box["width"] * 0.4, box["y"] + 60)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.6, box["y"] + 60, steps=5)
    page.mouse.up()
    expect(viewer.locator('[data-part="selection-text"]')).to_contain_text("selected")
    selection = page.evaluate("window.logViewers[0].state.selection")

    # At 1x the interval (a fifth of a view zoomed to about 6 s) takes about a second.
    viewer.locator('[data-part="speed"]').select_option("1")
    viewer.get_by_role("button", name="Play").click()
    expect(viewer.get_by_role("button", name="Pause")).to_be_visible()
    expect(viewer.get_by_role("button", name="Play")).to_be_visible(timeout=10_000)
    cursor = page.evaluate("window.logViewers[0].state.cursor")
    assert cursor == pytest.approx(selection[1])
    # The values tree followed the cursor to the end of the interval.
    expect(viewer.locator('[data-part="tree"]')).to_have_attribute("data-t", str(cursor))


def test_the_multi_plot_applies_scale_offset_and_colour_per_line(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    created = upload(client, write_dfi(tmp_path / "multi.dfi")).json()
    wait_until_processed(client, created["id"])
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{created['id']}/")
    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)
    plotted = "window.logViewers[0].multi.u.data.slice(1)"
    # The altitude is ticked to start with.
    page.wait_for_function(f"{plotted}.length === 1 && {plotted}[0].length === 3")
    assert page.evaluate(plotted) == [[0.5, 0.75, 1.25]]

    row = viewer.locator('[data-part="lines"] tr[data-path="navdata/Altitude"]')
    row.get_by_label("Scale of navdata/Altitude").fill("2")
    row.get_by_label("Offset of navdata/Altitude").fill("-1")
    page.wait_for_function(f"{plotted}[0][0] === 0")
    assert page.evaluate(plotted) == [[0.0, 0.5, 1.5]]

    row.get_by_label("Colour of navdata/Altitude").fill("#ff0000")
    page.wait_for_function(
        "(() => { const u = window.logViewers[0].multi.u; return u.series[1].stroke(u, 1) === '#ff0000'; })()"
    )

    viewer.locator('[data-part="picker"] input[value="navdata/Rotation/yaw"]').check()
    page.wait_for_function(f"{plotted}.length === 2 && {plotted}[1][2] === 93")
    assert viewer.locator('[data-part="lines"] tbody tr').count() == 2

    # A click on a value in the tree plots it too.
    viewer.locator('[data-part="tree"] [data-path="navdata/Motor powers/motor 1"]').click()
    expect(viewer.locator('[data-part="lines"] tbody tr')).to_have_count(3)
    page.wait_for_function(f"{plotted}.length === 3 && {plotted}[2][0] === 100")


def test_the_3d_view_turns_the_drone_yaw_then_pitch_then_roll_like_the_core(
    world_tx, live_logs, page
):
    from logs.analysis import rotation_matrix

    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/")
    angles = [(0.3, 0.2, -0.4), (1.2, -0.5, 0.9), (-2.0, 0.1, 0.0), (3.0, 1.0, -1.4)]
    matrices = page.evaluate(
        """async (angles) => {
            const m = await import('/static/js/logs/attitude.js');
            return angles.map(([y, p, r]) => m.rotationNED(y, p, r));
        }""",
        angles,
    )
    for (yaw, pitch, roll), matrix in zip(angles, matrices, strict=True):
        expected = rotation_matrix(yaw, pitch, roll)
        assert np.allclose(matrix, expected, atol=1e-12), (matrix, expected)


def test_a_log_page_opened_while_processing_shows_live_progress_then_the_viewer(
    world_tx, live_logs, page, tmp_path, monkeypatch
):
    """No worker here: the test runs the import itself once the page is watching."""
    from logs import services
    from logs.models import FlightLog

    source = tmp_path / "slow.bin"
    synthetic_dataflash(source, seconds=60)
    log = FlightLog.objects.create(
        organisation=world_tx.org, owner=world_tx.operator, name="slow.bin", size=1
    )
    log.upload_path.parent.mkdir(parents=True)
    source.rename(log.upload_path)

    frames: list[dict] = []

    def follow(ws):  # type: ignore[no-untyped-def]
        if "/ws/logs/" in ws.url:  # the portal's own sockets (fleet) say other things
            ws.on("framereceived", lambda payload: frames.append(json.loads(payload)))

    page.on("websocket", follow)
    login(page, live_logs, "viewer")
    page.goto(f"{live_logs.url}/logs/{log.pk}/")
    processing = page.locator('[data-part="processing"]')
    expect(processing).to_be_visible()
    expect(processing.locator("progress")).to_have_attribute("value", "0")
    # The socket's first frame is the status snapshot: from then on no event is missed.
    for _ in range(200):
        if any(f.get("type") == "status" for f in frames):
            break
        page.wait_for_timeout(50)  # lets Playwright deliver the frames
    assert frames and frames[0]["status"] == "processing"

    monkeypatch.setattr(services, "PROGRESS_INTERVAL_S", 0.0)

    def process() -> str:
        # Its own thread: publishing progress needs a thread without Playwright's loop.
        from django.db import connection

        try:
            return services.process_log(str(log.pk))
        finally:
            connection.close()

    with ThreadPoolExecutor(1) as pool:
        assert pool.submit(process).result() == "ready"

    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)
    expect(processing).to_be_hidden()
    progress = [f["progress"] for f in frames if f.get("type") == "progress"]
    assert len(progress) >= 3 and progress == sorted(progress)
    assert frames[-1]["status"] == "ready"


def test_the_upload_zone_explains_files_it_refuses(world_tx, page, tmp_path, logs_dir):
    from django.db import connection

    from tests.logs.conftest import QUEUE
    from tests.support.live import LiveServer

    server = LiveServer(
        connection.settings_dict["NAME"],
        extra_env={
            "LOGS_DIR": str(logs_dir),
            "LOGS_IMPORT_QUEUE": QUEUE,
            "LOG_UPLOAD_MAX_BYTES": "50000",
        },
    )
    try:
        login(page, server, "operator")
        page.goto(f"{server.url}/logs/")
        expect(page.locator("#dropzone")).to_contain_text("up to 48.8 KB each")
        big = tmp_path / "big.ulg"
        synthetic_ulog(big, seconds=10)
        photo = tmp_path / "holiday.jpg"
        photo.write_bytes(b"\xff\xd8\xff\xe0 not a flight log" * 10)
        page.set_input_files("#log-file", [str(big), str(photo)])
        items = page.locator("#uploads li")
        size = f"{big.stat().st_size / 1024:.1f} KB"
        expect(items.filter(has_text="big.ulg")).to_contain_text(
            f"Too large: {size}, over the limit of 48.8 KB."
        )
        expect(items.filter(has_text="holiday.jpg")).to_contain_text(
            "is not a flight log format we can read"
        )
        expect(page.locator("#uploads li.failed")).to_have_count(2)
    finally:
        server.stop()


def test_the_address_carries_the_view_so_a_shared_link_opens_the_same_moment(
    world_tx, worker, live_logs, page, tmp_path
):
    client = client_for(world_tx.operator)
    created = upload(client, write_dfi(tmp_path / "moment.dfi")).json()
    wait_until_processed(client, created["id"])
    login(page, live_logs, "viewer")
    page.goto(
        f"{live_logs.url}/logs/{created['id']}/#t=0.0017&sel=0.001~0.004&plot=navdata%2FRotation%2Fyaw"
    )
    viewer = page.locator("[data-log-viewer]")
    expect(viewer).to_have_attribute("data-loaded", "true", timeout=15_000)
    expect(viewer.locator('[data-part="clock"]')).to_have_text("t = 00:00.002")
    expect(viewer.locator('[data-part="selection-text"]')).to_contain_text("(0.003 s)")
    expect(viewer.locator('[data-part="lines"] tbody tr')).to_have_count(1)
    expect(viewer.locator('[data-part="lines"] tbody tr')).to_have_attribute(
        "data-path", "navdata/Rotation/yaw"
    )
    expect(viewer.locator('[data-path="navdata/Rotation/yaw"] .v')).to_have_attribute(
        "data-value", "91.5"
    )

    viewer.locator('[data-action="clear-selection"]').click()
    share = page.locator("#share-url")
    expect(share).to_have_value(
        re.compile(r"/logs/[0-9a-f-]+/#t=0\.0017&plot=navdata%2FRotation%2Fyaw$")
    )

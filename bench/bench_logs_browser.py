"""Time to first plot of a processed flight log in headless Chromium.

A 10-minute PX4 ULog (IMU and attitude at 250 Hz, position, GPS, battery) is imported into
its columnar store, then its page is opened in headless Chromium against the real ASGI app
(uvicorn) until the first uPlot chart has drawn data. The baseline is the same page's bare
HTML and CSS (JavaScript off), loaded in the same run: what any page costs before the
viewer starts. Both are measured from the navigation start, median of several loads.

Needs the test services (`scripts/services.sh start test`); creates and drops its own
database. Run: .venv/bin/python -m bench.bench_logs_browser
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import tempfile
from pathlib import Path

from bench.browser import launch_chromium, serve_app
from runtime.processes import Supervised

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_logs_browser_{os.getpid()}"

ROUNDS = 7
LOG_SECONDS = 600
GOAL = "first plot < 1 s after processing, a few thousand points per series"
PASSWORD = "correct horse battery staple"


def _prepare(logs_dir: Path) -> tuple[str, str]:
    """A database with one operator and one processed log; returns (database, log id)."""
    from django.conf import settings
    from django.db import connection

    settings.LOGS_DIR = str(logs_dir)
    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)

    from django.contrib.auth import get_user_model

    from fleet.models import Membership, Organisation, Role
    from logs import services
    from logs.models import FlightLog, LogStatus
    from logs.synth import synthetic_ulog

    org = Organisation.objects.create(name="Bench", slug="bench")
    user = get_user_model().objects.create_user("bench", password=PASSWORD)
    Membership.objects.create(user=user, organisation=org, role=Role.OPERATOR)
    source = logs_dir / "flight.ulg"
    synthetic_ulog(source, seconds=LOG_SECONDS)
    log = FlightLog.objects.create(
        organisation=org, owner=user, name=source.name, size=source.stat().st_size
    )
    log.upload_path.parent.mkdir(parents=True)
    shutil.move(source, log.upload_path)
    assert services.process_log(str(log.pk)) == LogStatus.READY
    return connection.settings_dict["NAME"], str(log.pk)


def _log_in(browser, base_url: str, javascript: bool):  # type: ignore[no-untyped-def]
    """A desktop-sized page of a fresh context, logged in as the bench operator."""
    context = browser.new_context(
        viewport={"width": 1440, "height": 900}, java_script_enabled=javascript
    )
    page = context.new_page()
    page.goto(f"{base_url}/accounts/login/")
    page.fill("input[name=username]", "bench")
    page.fill("input[name=password]", PASSWORD)
    page.click("button[type=submit]")
    page.wait_for_load_state()
    return context, page


def _first_plot(page, page_url: str) -> tuple[float, int, int]:  # type: ignore[no-untyped-def]
    """One load with JavaScript: (ms to the first drawn chart, series bytes, most points)."""
    from playwright.sync_api import Error as PlaywrightError

    sizes: list[int] = []
    points: list[int] = []

    def on_response(response) -> None:  # type: ignore[no-untyped-def]
        if "/series/" not in response.url or not response.ok:
            return
        try:
            body = response.body()
        except PlaywrightError:
            return  # aborted by a newer request for the same chart
        sizes.append(len(body))
        points.append(len(json.loads(body)["t"]))

    page.on("response", on_response)
    page.goto(page_url)
    page.wait_for_function("document.documentElement.dataset.firstPlot", timeout=30_000)
    first = float(page.evaluate("document.documentElement.dataset.firstPlot"))
    page.wait_for_load_state("networkidle")
    page.remove_listener("response", on_response)
    return first, sum(sizes), max(points, default=0)


def _bare_html(page, page_url: str) -> float:  # type: ignore[no-untyped-def]
    """One load without JavaScript: ms to the load event."""
    page.goto(page_url, wait_until="load")
    return page.evaluate("performance.getEntriesByType('navigation')[0].loadEventEnd")


def _measure(base_url: str, log_id: str) -> dict:
    from playwright.sync_api import sync_playwright

    page_url = f"{base_url}/logs/{log_id}/"
    loads: list[tuple[float, int, int]] = []
    bare_html: list[float] = []
    with sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        try:
            context, page = _log_in(browser, base_url, javascript=True)
            loads = [_first_plot(page, page_url) for _ in range(ROUNDS)]
            context.close()
            context, page = _log_in(browser, base_url, javascript=False)
            bare_html = [_bare_html(page, page_url) for _ in range(ROUNDS)]
            context.close()
        finally:
            browser.close()
    return {
        "first_plot_s": statistics.median(load[0] for load in loads) / 1000,
        "bare_html_s": statistics.median(bare_html) / 1000,
        "series_bytes": int(statistics.median(load[1] for load in loads)),
        "max_points_per_series": max(load[2] for load in loads),
    }


def _live_server(database: str, logs_dir: Path) -> Supervised:
    """The ASGI app under uvicorn on the bench database, its logs in `logs_dir`."""
    return serve_app(database, logs_dir, LOGS_DIR=str(logs_dir))


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    from bench.common import record

    original_database = connection.settings_dict["NAME"]
    logs_dir = Path(tempfile.mkdtemp(prefix="bench-logs-"))
    server = None
    try:
        database, log_id = _prepare(logs_dir)
        server = _live_server(database, logs_dir)
        result = _measure(server.url, log_id)
        record(
            "logs.first_plot_s",
            value=result["first_plot_s"],
            unit="s",
            baseline_name="the same page's bare HTML and CSS (JavaScript off)",
            baseline_value=result["bare_html_s"],
            higher_is_better=False,
            goal=GOAL,
            log_seconds=LOG_SECONDS,
            series_bytes_first_view=result["series_bytes"],
            max_points_per_series=result["max_points_per_series"],
        )
    finally:
        if server is not None:
            server.stop()
        if connection.settings_dict["NAME"] != original_database:
            connection.close()
            connection.creation.destroy_test_db(original_database, verbosity=0)
        shutil.rmtree(logs_dir, ignore_errors=True)


if __name__ == "__main__":
    main()

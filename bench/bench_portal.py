"""Time until the fleet page is usable with 2 000 and 10 000 drones, in headless Chromium.

"Usable": from the navigation start until the page's first table page is drawn and the
socket's snapshot has put every drone on the (clustered) map: the HTML, the scripts, the
table API's first page and the websocket's first message, as a user waits for them
(the page notes the moment on <html data-fleet-ready>). The baseline is the same page of an
organisation without drones, loaded in the same run (to its load event: it has nothing
more to wait for). Median of several loads each; the bytes of the HTML, the table page and
the snapshot are recorded beside, and the median moment of each step the page marks
(`performance.mark`: its head's script runs and opens the socket, the socket is open, the
snapshot is merged, the table page is drawn), to show where a slow load spends its time.

Needs the test services (`scripts/services.sh start test`); creates and drops its own
database. Run: .venv/bin/python -m bench.bench_portal
"""

from __future__ import annotations

import os
import random
import shutil
import statistics
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from bench.browser import launch_chromium, serve_app

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_portal_{os.getpid()}"

ROUNDS = 5
SIZES = (2000, 10000)
# The page's own marks, in the order a load usually passes them (ms since navigation start).
MARKS = ("fleet:early", "fleet:socket-open", "fleet:table", "fleet:snapshot")
GOAL = "the fleet page usable in under 1 s with 2 000 and with 10 000 drones"
PASSWORD = "correct horse battery staple"


def _drones(org, count: int) -> None:  # type: ignore[no-untyped-def]
    """`count` drones spread over a 10 km square, in every state."""
    from fleet.models import Drone

    rng = random.Random(count)
    now = datetime.now(UTC)
    Drone.objects.bulk_create(
        [
            Drone(
                organisation=org,
                drone_id=f"{org.slug.upper()}_{i:05d}",
                online=rng.random() > 0.1,
                last_seen=now,
                lat=40.60 + rng.random() * 0.09,
                lon=-8.70 + rng.random() * 0.12,
                alt=rng.choice([0.0, 0.0, 12.0, 30.0]),
                battery_voltage=15.2,
                battery_remaining=rng.random(),
                armed=rng.random() > 0.5,
                airborne=rng.random() > 0.5,
                flight_mode=rng.choice(["PositionHold", "RTL", "Stabilized1"]),
                mission={"mission_id": "survey", "index": i % 90} if i % 3 == 0 else None,
                fc={"protocol": "uavtalk", "connected": True, "clock_offset_s": 0.1},
            )
            for i in range(count)
        ],
        batch_size=2000,
    )


def _prepare() -> str:
    """A database with one organisation (and one member) per fleet size, and a bare one."""
    from django.contrib.auth import get_user_model
    from django.db import connection

    from fleet.models import Membership, Organisation, Role

    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    for size in (0, *SIZES):
        org = Organisation.objects.create(name=f"Fleet {size}", slug=f"fleet{size}")
        user = get_user_model().objects.create_user(f"bench{size}", password=PASSWORD)
        Membership.objects.create(user=user, organisation=org, role=Role.OPERATOR)
        _drones(org, size)
    return connection.settings_dict["NAME"]


def _log_in(browser, base_url: str, size: int):  # type: ignore[no-untyped-def]
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    page.goto(f"{base_url}/accounts/login/")
    page.fill("input[name=username]", f"bench{size}")
    page.fill("input[name=password]", PASSWORD)
    page.click("button[type=submit]")
    page.wait_for_load_state()
    return context, page


def _one_load(page, base_url: str, size: int) -> dict:  # type: ignore[no-untyped-def]
    """One load of the fleet page: ms until usable, and the bytes it waited for."""
    sizes = {"html": 0, "table": 0, "snapshot": 0}

    def on_response(response) -> None:  # type: ignore[no-untyped-def]
        from playwright.sync_api import Error as PlaywrightError

        key = "html" if response.url.rstrip("/") == base_url else None
        key = "table" if "/fleet/table/" in response.url else key
        if key is None:
            return
        try:
            sizes[key] = len(response.body())
        except PlaywrightError:
            pass  # a periodic refresh cut short by the next navigation

    def on_socket(socket) -> None:  # type: ignore[no-untyped-def]
        if "/ws/fleet/" not in socket.url:
            return  # the alerts banner's socket

        def on_frame(payload) -> None:  # type: ignore[no-untyped-def]
            if not sizes["snapshot"]:
                sizes["snapshot"] = len(payload)

        socket.on("framereceived", on_frame)

    page.on("response", on_response)
    page.on("websocket", on_socket)
    page.goto(f"{base_url}/")
    if size:
        page.wait_for_function("document.documentElement.dataset.fleetReady", timeout=60_000)
        ready = float(page.evaluate("document.documentElement.dataset.fleetReady"))
        markers = page.evaluate("skyhiveFleet.markerIds().length")
        assert markers == size, f"{markers} of {size} drones on the map"
        marks = page.evaluate(
            "Object.fromEntries(performance.getEntriesByType('mark').map(m => [m.name, m.startTime]))"
        )
        sizes.update({name: marks.get(name) for name in MARKS})
    else:
        page.wait_for_load_state("load")
        ready = page.evaluate("performance.getEntriesByType('navigation')[0].loadEventEnd")
    page.remove_listener("response", on_response)
    page.remove_listener("websocket", on_socket)
    return {"ms": ready, **sizes}


def _median_marks(loads: list[dict]) -> dict[str, float]:
    """The median moment of each page mark over the loads that reached it."""
    medians = {}
    for name in MARKS:
        seen = [load[name] for load in loads if load.get(name) is not None]
        if seen:
            medians[name.removeprefix("fleet:")] = round(statistics.median(seen), 1)
    return medians


def _measure(base_url: str) -> dict[int, dict]:
    from playwright.sync_api import sync_playwright

    results: dict[int, dict] = {}
    with sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        try:
            for size in (0, *SIZES):
                context, page = _log_in(browser, base_url, size)
                _one_load(page, base_url, size)  # warm the server's code paths and caches
                loads = [_one_load(page, base_url, size) for _ in range(ROUNDS)]
                context.close()
                results[size] = {
                    "s": statistics.median(load["ms"] for load in loads) / 1000,
                    **{k: loads[-1][k] for k in ("html", "table", "snapshot")},
                    "marks_ms": _median_marks(loads),
                }
        finally:
            browser.close()
    return results


def _server_times(size: int) -> dict:
    """In this process, on the same database: the server's share of a load, best of 5."""
    import json

    from bench.common import best_of
    from fleet import listing
    from fleet.models import Organisation

    org = Organisation.objects.get(slug=f"fleet{size}")
    query = listing.TableQuery()
    return {
        "snapshot_server_s": best_of(lambda: json.dumps(listing.marker_columns(org.pk))),
        "table_page_server_s": best_of(lambda: json.dumps(listing.table_page(org.pk, query))),
    }


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    from bench.common import record

    original_database = connection.settings_dict["NAME"]
    logs_dir = Path(tempfile.mkdtemp(prefix="bench-portal-"))
    server = None
    try:
        server = serve_app(_prepare(), logs_dir)
        results = _measure(server.url)
        bare = results[0]
        for size in SIZES:
            got = results[size]
            record(
                f"portal.fleet_page_{size}_s",
                value=got["s"],
                unit="s",
                baseline_name="the fleet page of an organisation without drones",
                baseline_value=bare["s"],
                higher_is_better=False,
                goal=GOAL,
                measured="headless Chromium, navigation start to first table page drawn "
                "and every drone on the map (HTML + scripts + table API + socket snapshot)",
                drones=size,
                html_bytes=got["html"],
                table_page_bytes=got["table"],
                snapshot_bytes=got["snapshot"],
                baseline_html_bytes=bare["html"],
                marks_ms=got["marks_ms"],
                **_server_times(size),
            )
            print(f"  {size} drones, median page marks (ms since navigation): {got['marks_ms']}")
    finally:
        if server is not None:
            server.stop()
        if connection.settings_dict["NAME"] != original_database:
            connection.close()
            connection.creation.destroy_test_db(original_database, verbosity=0)
        shutil.rmtree(logs_dir, ignore_errors=True)


if __name__ == "__main__":
    main()

"""Offline first, in a real browser: every page of the portal, on a laptop and on a phone,
asks nothing of any other host and logs no console error; maps draw their scale and grid
without tiles (the laptop's visit), and with imported tiles take them from the portal
itself (the phone's)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from urllib.parse import urlparse

import pytest
from django.urls import URLPattern, URLResolver, get_resolver

from tests.conftest import login
from tests.tiles.mbtiles import write_mbtiles

pytestmark = pytest.mark.browser

ULOG = Path(__file__).resolve().parents[1] / "data" / "ulog" / "sample_log_small.ulg"

# Every route of the URL confs, as the page the browser opens ({mission}, {log} filled in
# by the test), or None with the reason it is not a page of its own.
ROUTES: dict[str, str | None] = {
    "": "/",
    "drones/<str:drone_id>/": "/drones/ACME_1/",
    "organisation/envelope/": "/organisation/envelope/",
    "missions/": "/missions/",
    "missions/plan/": "/missions/plan/",
    "missions/log-viewer/": "/missions/log-viewer/",
    "missions/panic/": "/missions/panic/",
    "missions/<uuid:pk>/": "/missions/{mission}/",
    "telemetry/": "/telemetry/",
    "telemetry/status/": "/telemetry/status/",
    "telemetry/drones/<str:drone_id>/": "/telemetry/drones/ACME_1/",
    "pastview/<str:drone_id>/": "/pastview/ACME_1/",
    "video/": "/video/",
    "logs/": "/logs/",
    "logs/compare/": "/logs/compare/?ids={log}",
    "logs/<uuid:pk>/": "/logs/{log}/",
    "logs/trends/": "/logs/trends/",
    "logs/trends/<str:drone_id>/": "/logs/trends/ACME_1/",
    # Needs two logs: tests/logs/test_trends_browser.py walks it.
    "logs/compare/overlay/": None,
    "operations/": "/operations/",
    "records/drones/<str:drone_id>/": "/records/drones/ACME_1/",
    "records/pilots/<str:username>/": "/records/pilots/operator/",
    # Needs a recorded flight (only flights make records): tests/records/test_logbook_browser.py.
    "records/flights/<int:pk>/": None,
    "maintenance/": "/maintenance/",
    "maintenance/drones/<str:drone_id>/": "/maintenance/drones/ACME_1/",
    "checklists/": "/checklists/",
    "checklists/drones/<str:drone_id>/": "/checklists/drones/ACME_1/",
    "batteries/": "/batteries/",
    "batteries/drones/<str:drone_id>/choose/": None,  # POST only
    "batteries/rules/": None,  # POST only
    "accounts/password/": "/accounts/password/",
    "accounts/password/done/": "/accounts/password/done/",
    "api/docs/": "/api/docs/",
    "api/redoc/": "/api/redoc/",
    "api/v1/": "/api/v1/",  # the browsable API
    "admin/": "/admin/",  # a non-staff user gets the admin's sign-in page
    "accounts/security/": "/accounts/security/",
    "accounts/security/two-factor/": "/accounts/security/two-factor/",
    "accounts/audit/": "/accounts/audit/",
    "accounts/password/reset/": "/accounts/password/reset/",
    "accounts/password/reset/sent/": "/accounts/password/reset/sent/",
    "accounts/password/reset/done/": "/accounts/password/reset/done/",
    "accounts/members/": None,  # admins only: 403 for the operator signed in here
    "accounts/organisation/": None,  # admins only
    "accounts/login/code/": None,  # only during a sign-in with a second factor
    "accounts/invitation/<str:key>/": None,  # needs an invitation's secret key
    "accounts/password/reset/<uidb64>/<token>/": None,  # needs a reset token
    "accounts/audit.csv": None,  # a CSV download
    "accounts/security/tokens/": None,  # POST only
    "accounts/security/tokens/<int:pk>/revoke/": None,  # POST only
    "accounts/security/tokens/legacy/revoke/": None,  # POST only
    "accounts/security/two-factor/disable/": None,  # POST only
    "accounts/members/invite/": None,  # POST only
    "accounts/members/<int:pk>/role/": None,  # POST only
    "accounts/members/<int:pk>/remove/": None,  # POST only
    "accounts/invitations/<int:pk>/revoke/": None,  # POST only
    "fleet/table/": None,  # JSON for the fleet page's table
    "accounts/login/": None,  # opened signed out, before the rest
    "accounts/logout/": None,  # POST only
    "organisation/switch/": None,  # POST only
    "health": None,  # JSON
    "favicon.ico": None,  # the icon
    "control": None,  # the /control REST command table (JSON)
    "api/schema/": None,  # the OpenAPI document (YAML)
    "tiles/<int:z>/<int:x>/<int:y>.<str:ext>": None,  # images
    "missions/pictures/<int:pk>/": None,  # images
    "missions/pictures/<int:pk>/thumbnail/": None,  # images
    "logs/<uuid:pk>/download/": None,  # a file download
    "logs/collection/<str:drone_id>/": None,  # POST only (the drone page's form)
    "pastview/api/<str:drone_id>/settings/": None,  # JSON
}


def routes(patterns: list | None = None, prefix: str = "") -> list[str]:
    """Every route of the URL confs; the admin and the REST API count as one page each."""
    found = []
    for entry in get_resolver().url_patterns if patterns is None else patterns:
        route = prefix + str(entry.pattern)
        if isinstance(entry, URLResolver) and route not in ("admin/", "api/v1/"):
            found += routes(entry.url_patterns, route)
        elif isinstance(entry, (URLPattern, URLResolver)):
            found.append(route)
    return found


def test_every_route_of_the_portal_is_listed_here():
    assert sorted(set(routes()) - set(ROUTES)) == []


@pytest.fixture(scope="module")
def offline_dirs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("offline")
    return {"LOGS_DIR": root / "logs", "TILES_DIR": root / "tiles"}


@pytest.fixture(scope="module")
def live_offline(request, offline_dirs):  # type: ignore[no-untyped-def]
    request.getfixturevalue("django_db_setup")
    from django.db import connection

    from tests.support.live import LiveServer

    env = {name: str(path) for name, path in offline_dirs.items()}
    server = LiveServer(connection.settings_dict["NAME"], extra_env=env)
    yield server
    server.stop()


@pytest.fixture
def portal(world_tx, settings, offline_dirs) -> dict[str, str]:  # type: ignore[no-untyped-def]
    """An operator's organisation with a drone (the world's), a mission and a flight log."""
    from logs.models import FlightLog
    from logs.services import process_log
    from missions.models import Mission, Step
    from missions.planning import mission_steps

    settings.LOGS_DIR = str(offline_dirs["LOGS_DIR"])
    settings.TILES_DIR = str(offline_dirs["TILES_DIR"])
    mission = Mission.objects.create(
        organisation=world_tx.org, name="survey", created_by=world_tx.operator
    )
    waypoints = [[38.7369, -9.1427], [38.7372, -9.1420]]
    for step in mission_steps(waypoints, altitude=10):
        Step.objects.create(mission=mission, **step)
    log = FlightLog(organisation=world_tx.org, owner=world_tx.operator, name=ULOG.name)
    log.size = ULOG.stat().st_size
    log.upload_path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(ULOG, log.upload_path)
    log.save()
    process_log(str(log.pk))
    return {"mission": str(mission.pk), "log": str(log.pk)}


class Watch:
    """Every request a page makes and every console error it logs."""

    def __init__(self, page, host: str) -> None:  # type: ignore[no-untyped-def]
        self.host = host
        self.outside: list[str] = []
        self.errors: list[str] = []
        self.tiles: list[tuple[int, str]] = []
        page.on("request", self.request)
        page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        page.on("pageerror", lambda e: self.errors.append(str(e)))
        page.on("response", self.response)

    def request(self, request) -> None:  # type: ignore[no-untyped-def]
        url = urlparse(request.url)
        if url.scheme in ("data", "blob"):
            return
        if url.hostname != self.host:
            self.outside.append(request.url)

    def response(self, response) -> None:  # type: ignore[no-untyped-def]
        if "/tiles/" in response.url:
            self.tiles.append((response.status, response.url))


def map_pages(ids: dict[str, str], width: int) -> list[str]:
    """The pages that draw a geographic map on their first screen (the log's map is drawn once
    scrolled into view, which a phone's first screen is not)."""
    maps = ["/", "/organisation/envelope/", "/missions/plan/", f"/missions/{ids['mission']}/"]
    return maps + ([f"/logs/{ids['log']}/"] if width > 1000 else [])


def visit_every_page(browser, server, ids: dict[str, str], width: int, height: int) -> dict:
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    watch = Watch(page, urlparse(server.url).hostname)
    seen: dict[str, dict] = {}
    try:
        page.goto(f"{server.url}/accounts/login/", wait_until="networkidle")
        login(page, server, "operator")
        for url in sorted({u.format(**ids) for u in ROUTES.values() if u}):
            before = (len(watch.outside), len(watch.errors))
            response = page.goto(f"{server.url}{url}", wait_until="networkidle")
            if url in map_pages(ids, width):  # the map's scale and grid are drawn by script
                page.locator(".map-grid-label").nth(1).wait_for(timeout=15_000)
            page.wait_for_timeout(300)  # late scripts (charts) finish drawing
            assert response is not None and response.status == 200, url
            seen[url] = {
                "outside": watch.outside[before[0] :],
                "errors": watch.errors[before[1] :],
                "maps": page.locator(".leaflet-container").count(),
                "scales": page.locator(".leaflet-control-scale").count(),
                "grid": page.locator(".map-grid-label").count(),
            }
    finally:
        context.close()
    return {"pages": seen, "tiles": watch.tiles}


def assert_offline(visited: dict[str, dict], ids: dict[str, str], width: int) -> None:
    """Every page was opened, none asked another host or logged an error, and each
    geographic map has its scale and grid."""
    problems = {url: v for url, v in visited.items() if v["outside"] or v["errors"]}
    assert problems == {}, problems
    for url in map_pages(ids, width):
        page = visited[url]
        assert page["maps"] >= 1 and page["scales"] >= 1 and page["grid"] >= 2, url
    assert len(visited) == len([u for u in ROUTES.values() if u])


def test_no_page_asks_another_host_or_logs_an_error(browser, live_offline, portal):
    # On a laptop, with no tiles imported: the maps still draw their scale and grid.
    visited = visit_every_page(browser, live_offline, portal, 1280, 800)["pages"]
    assert_offline(visited, portal, 1280)


def lisbon_pyramid(zooms: range, west: float, south: float, east: float, north: float) -> dict:
    """Every XYZ tile touching the box at each zoom."""
    area = {}
    for z in zooms:
        n = 2**z

        def row(lat: float) -> int:
            return int((1 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2 * n)  # noqa: B023

        xs = range(int((west + 180) / 360 * n), int((east + 180) / 360 * n) + 1)
        area[z] = [(x, y) for x in xs for y in range(row(north), row(south) + 1)]
    return area


def test_on_a_phone_imported_tiles_come_from_the_portal(
    browser, live_offline, portal, offline_dirs, tmp_path
):
    # Last in this module: the tiles stay imported in the module's tiles folder.
    from tiles.importer import import_path

    box = (-9.20, 38.70, -9.08, 38.78)
    area = lisbon_pyramid(range(11, 16), *box)
    bounds = ",".join(str(v) for v in box)
    write_mbtiles(tmp_path / "lisbon.mbtiles", area, {"bounds": bounds, "minzoom": "11"})
    import_path(tmp_path / "lisbon.mbtiles")
    visited = visit_every_page(browser, live_offline, portal, 390, 844)
    assert_offline(visited["pages"], portal, 390)
    statuses = {status for status, _ in visited["tiles"]}
    assert visited["tiles"] and statuses <= {200, 304}, visited["tiles"][:5]

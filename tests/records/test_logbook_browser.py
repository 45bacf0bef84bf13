"""The logbook pages in a real browser: from the drone page to its logbook, totals by
month and year, the CSV download, a flight's page with its track, a member's logbook."""

from __future__ import annotations

import csv
import io
from datetime import UTC, datetime, timedelta

import pytest

from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def _record(world, started: datetime, minutes: float, distance: float):  # type: ignore[no-untyped-def]
    from records.models import FlightRecord, Origin

    return FlightRecord.objects.create(
        organisation=world.org,
        drone=world.drone,
        drone_ident=world.drone.drone_id,
        origin=Origin.COMMAND,
        pilot=world.operator,
        pilot_name="operator",
        started_at=started,
        ended_at=started + timedelta(minutes=minutes),
        duration_s=minutes * 60,
        distance_m=distance,
        max_height_m=25.0,
        battery_start=0.95,
        battery_end=0.6,
        track=[[0, 0, 0, 0], [30, 50, 0, 20], [60, 50, 40, 20], [90, 0, 0, 0]],
    )


def test_a_member_reads_a_drones_logbook_and_downloads_it(page, live_asgi, world_tx):
    _record(world_tx, datetime(2025, 11, 3, 10, tzinfo=UTC), 30, 1200.0)
    _record(world_tx, datetime(2026, 1, 5, 9, tzinfo=UTC), 15, 800.0)
    newest = _record(world_tx, datetime(2026, 1, 20, 9, tzinfo=UTC), 45, 2000.0)
    login(page, live_asgi, "viewer")
    page.goto(f"{live_asgi.url}/drones/ACME_1/")
    page.click("#drone-logbook")
    page.wait_for_load_state()
    assert page.locator("h1").inner_text() == "Logbook of drone ACME_1"
    assert page.locator("#logbook-flights tbody tr[data-flight]").count() == 3
    overall = page.locator("#logbook-overall")
    assert overall.locator("[data-flights]").inner_text() == "3"
    assert overall.locator("[data-hours]").inner_text() == "1.50"
    months = page.locator("#logbook-totals tbody tr")
    assert [months.nth(i).get_attribute("data-period") for i in range(months.count())] == [
        "2026-01",
        "2025-11",
    ]
    page.select_option("select[name=period]", "year")
    page.click("#logbook-filters button[type=submit]")
    page.wait_for_load_state()
    row = page.locator('#logbook-totals tr[data-period="2026"] td')
    assert [row.nth(i).inner_text() for i in range(3)] == ["2026", "2", "1.00"]

    with page.expect_download() as download:
        page.click("#logbook-csv")
    rows = list(csv.DictReader(io.StringIO(open(download.value.path()).read())))
    assert [r["started_at"][:10] for r in rows] == ["2026-01-20", "2026-01-05", "2025-11-03"]
    assert rows[0]["distance_m"] == "2000" and rows[0]["pilot"] == "operator"

    page.click(f'#logbook-flights tr[data-flight="{newest.pk}"] a')
    page.wait_for_load_state()
    assert page.locator("#flight-figures [data-duration]").inner_text().startswith("2700 s")
    assert page.locator("#flight-track polyline").count() == 1
    page.click("text=Logbook of operator")
    page.wait_for_load_state()
    assert page.locator("h1").inner_text() == "Logbook of pilot operator"
    assert page.locator("#logbook-flights tbody tr[data-flight]").count() == 3


def test_a_member_finds_their_own_logbook_from_their_account(page, live_asgi, world_tx):
    _record(world_tx, datetime(2026, 2, 1, 8, tzinfo=UTC), 10, 500.0)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/accounts/security/")
    page.click("#own-logbook")
    page.wait_for_load_state()
    assert page.locator("h1").inner_text() == "Logbook of pilot operator"
    assert page.locator("#logbook-flights tbody tr[data-flight]").count() == 1
